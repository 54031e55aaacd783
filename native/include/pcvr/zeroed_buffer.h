/// @file zeroed_buffer.h
/// @brief Image-sized arrays that start out as zeros without being written.
///
/// An image at magnification 8 is tens of megabytes, and so is a regular splat grid. A std::vector
/// of zeros faults in every 4 KiB page and then writes every byte again, although the kernel hands
/// out pages that are already zero. A ZeroedBuffer maps its storage straight from the kernel as
/// transparent huge pages where it can (a 50 MB image then takes about 25 faults instead of
/// 12,000), and faults them in up front on all cores: the kernel clears them, once.
#pragma once

#include <cstddef>
#include <utility>

namespace pcvr {

namespace detail {
/// Fresh zero pages for `bytes` (not 0); throws std::bad_alloc when the kernel has none.
void* map_zero_pages(size_t bytes);
void unmap_pages(void* data, size_t bytes) noexcept;
}  // namespace detail

/// A fixed-size array of T, all zero bits at construction; move-only.
template <class T>
class ZeroedBuffer {
public:
    ZeroedBuffer() = default;
    explicit ZeroedBuffer(size_t size)
        : data_(size ? static_cast<T*>(detail::map_zero_pages(size * sizeof(T))) : nullptr), size_(size) {}
    ZeroedBuffer(ZeroedBuffer&& other) noexcept : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}
    ZeroedBuffer& operator=(ZeroedBuffer&& other) noexcept {
        std::swap(data_, other.data_);
        std::swap(size_, other.size_);
        return *this;
    }
    ZeroedBuffer(const ZeroedBuffer&) = delete;
    ZeroedBuffer& operator=(const ZeroedBuffer&) = delete;
    ~ZeroedBuffer() {
        if (data_) detail::unmap_pages(data_, size_ * sizeof(T));
    }

    size_t size() const { return size_; }
    T* data() { return data_; }
    const T* data() const { return data_; }
    T& operator[](size_t i) { return data_[i]; }
    const T& operator[](size_t i) const { return data_[i]; }
    T* begin() { return data_; }
    T* end() { return data_ + size_; }
    const T* begin() const { return data_; }
    const T* end() const { return data_ + size_; }

private:
    T* data_ = nullptr;
    size_t size_ = 0;
};

}  // namespace pcvr
