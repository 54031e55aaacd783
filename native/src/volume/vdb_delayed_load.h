/// @file vdb_delayed_load.h
/// @brief The check of OpenVDB's delayed-load metadata, a per-leaf table OpenVDB writes for delayed
/// loading and sizes from the file blindly. PCVR never delay-loads (a grid that reads is complete), but
/// every file carries the table and OpenVDB parses it with the grid's metadata.
#pragma once

#include <openvdb/io/DelayedLoadMetadata.h>

#include <array>
#include <limits>
#include <string>

#include "volume/vdb_stream.h"

namespace pcvr::vdb_reader {

/// DelayedLoadMetadata (ending at `end`) holds a per-leaf mask and a per-leaf size table, each
/// stored raw or as one blosc chunk: [leaf count][bytes][mask][bytes][sizes], bytes 0 for raw
/// data, and 0xFFFFFFFF for no sizes. OpenVDB resizes the tables to the count blindly and hands
/// blosc the chunk's own header, which blosc trusts (fuzzing found a corrupt one that made it
/// read past a 56-byte buffer): the count, both sizes and each chunk's header must agree.
/// Leaves the stream where it was.
inline void check_delayed_load_table(SizedStream& file, int64_t end, const char* what) {
    const int64_t start = file.tell();
    const std::string corrupt = std::string("corrupt ") + what + " (delayed-load table)";
    if (end - start < 8) file.corrupt(corrupt);
    const uint32_t leaves = file.read_u32();
    if (int64_t(leaves) > file.size) file.corrupt(corrupt);  // each leaf takes far more than a byte of the file
    auto table = [&](int64_t bytes_per_leaf, bool optional) {
        if (end - file.tell() < 4) file.corrupt(corrupt);
        const uint32_t stored = file.read_u32();
        if (optional && stored == std::numeric_limits<uint32_t>::max()) return;
        const int64_t raw = int64_t(leaves) * bytes_per_leaf;
        if ((stored == 0 ? raw : int64_t(stored)) > end - file.tell()) file.corrupt(corrupt);
        if (stored == 0) {
            file.is.seekg(raw, std::ios::cur);
            return;
        }
        std::array<uint8_t, 16> header{};  // blosc: uncompressed size at byte 4, chunk size at 12
        if (stored < header.size()) file.corrupt(corrupt);
        file.is.read(reinterpret_cast<char*>(header.data()), std::streamsize(header.size()));
        // OpenVDB pads tables under 128 bytes to 128 before compressing them.
        const int64_t uncompressed = little_endian_u32(header, 4);
        if (!(uncompressed == raw || (raw < 128 && uncompressed == 128)) || little_endian_u32(header, 12) != stored)
            file.corrupt(corrupt);
        file.is.seekg(int64_t(stored) - int64_t(header.size()), std::ios::cur);
    };
    table(sizeof(vdb::io::DelayedLoadMetadata::MaskType), false);
    table(sizeof(vdb::io::DelayedLoadMetadata::CompressedSizeType), true);
    file.is.seekg(start);
}

}  // namespace pcvr::vdb_reader
