/// @file vdb_stream.h
/// @brief A VDB file's input stream that knows the file's size, so that no length read from the file
/// is trusted: the primitives the reader (vdb_reader.h) and its layout check (vdb_layout_check.h) share.
///
/// The stream throws on the first short read; a length field beyond the bytes left is a corrupt file.
/// Private to the VDB reader.
#pragma once

#include <openvdb/io/io.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <string>

#include "pcvr/errors.h"

namespace pcvr::vdb_reader {

namespace vdb = openvdb;

inline std::string quoted(const std::string& s) { return "'" + s + "'"; }

/// `s` with every byte that is not part of valid UTF-8 replaced by U+FFFD. Names and messages read
/// from a file go to Python as str, which a corrupt or Latin-1 name would otherwise break.
inline std::string valid_utf8(const std::string& s) {
    std::string out;
    out.reserve(s.size());
    const auto* p = reinterpret_cast<const unsigned char*>(s.data());
    const size_t n = s.size();
    for (size_t i = 0; i < n;) {
        const unsigned char c = p[i];
        size_t len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
        bool ok = len > 0 && i + len <= n && !(len == 2 && c < 0xC2) && !(len == 4 && c > 0xF4);
        for (size_t k = 1; ok && k < len; ++k) ok = (p[i + k] & 0xC0) == 0x80;
        if (ok && len == 3) {  // no overlong forms, no UTF-16 surrogates
            ok = !(c == 0xE0 && p[i + 1] < 0xA0) && !(c == 0xED && p[i + 1] >= 0xA0);
        } else if (ok && len == 4) {
            ok = !(c == 0xF0 && p[i + 1] < 0x90) && !(c == 0xF4 && p[i + 1] >= 0x90);
        }
        if (ok) {
            out.append(s, i, len);
            i += len;
        } else {
            out += "\xEF\xBF\xBD";
            ++i;
        }
    }
    return out;
}

/// The little-endian 32-bit word at byte `at` of a chunk header (blosc stores its sizes so).
inline uint32_t little_endian_u32(const std::array<uint8_t, 16>& header, int at) {
    return uint32_t(header[at]) | uint32_t(header[at + 1]) << 8 | uint32_t(header[at + 2]) << 16 |
           uint32_t(header[at + 3]) << 24;
}

/// An open VDB file: its path, its stream (tagged with the file's versions and compression by the
/// reader) and its size. Not thread-safe: one position.
struct SizedStream {
    std::string path;
    std::ifstream is;
    int64_t size = 0;
    vdb::io::StreamMetadata::Ptr meta;  ///< the stream metadata the reader tagged `is` with

    [[noreturn]] void corrupt(const std::string& what) const {
        throw VdbReadError("cannot read " + quoted(path) + ": " + what);
    }

    int64_t tell() { return int64_t(is.tellg()); }
    int64_t remaining() { return size - tell(); }

    uint32_t read_u32() {
        uint32_t v = 0;
        is.read(reinterpret_cast<char*>(&v), sizeof(v));
        return v;
    }

    /// Read a length-prefixed string, refusing lengths beyond the end of the file.
    std::string read_string(const char* what) {
        const uint32_t n = read_u32();
        if (int64_t(n) > remaining()) corrupt(std::string("corrupt ") + what + " (string length " + std::to_string(n) + ")");
        std::string s(n, '\0');
        if (n) is.read(&s[0], n);
        return s;
    }

    /// Check the next `n` length-prefixed strings fit in the file; leaves the stream where it was.
    void check_strings(int n, const char* what) {
        const int64_t start = tell();
        for (int i = 0; i < n; ++i) {
            const uint32_t len = read_u32();
            if (int64_t(len) > remaining()) corrupt(std::string("corrupt ") + what + " (string length " + std::to_string(len) + ")");
            is.seekg(len, std::ios::cur);
        }
        is.seekg(start);
    }
};

}  // namespace pcvr::vdb_reader
