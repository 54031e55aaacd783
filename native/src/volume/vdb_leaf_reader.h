/// @file vdb_leaf_reader.h
/// @brief Decoding a streamed grid's leaves from their records in the file, on all threads (grid_stream.cpp).
///
/// Reader::read_topology gives the leaves without values and where each one's record starts; this fills
/// a batch of them. OpenVDB's LeafNode::readBuffers decodes a record (decompression included) from a
/// stream tagged with the file's versions and compression, so each task opens a stream of its own and
/// tags it as the reader's.
#pragma once

#include <openvdb/io/io.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "pcvr/errors.h"
#include "volume/vdb_stream.h"

namespace pcvr::vdb_reader {

/// Fill the values of `leaves` (their value masks set by read_topology) from their records in `file`:
/// leaves[i] is leaf number `numbers[i]` of the tree's leaf order, whose record starts at
/// `positions[numbers[i]]`. A run of leaves a task, each through a stream of its own tagged as `file`'s,
/// with its own copy of the stream metadata (OpenVDB counts the leaves it reads in it); consecutive
/// numbers read on without a seek. `file`'s own stream is not moved.
template <typename Leaf>
void read_leaves_parallel(const SizedStream& file, const std::vector<Leaf*>& leaves, const std::vector<size_t>& numbers,
                          const int64_t* positions, bool half) {
    constexpr size_t kLeavesPerTask = 64;  // 128 KiB of values: a file open is noise beside it
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), kLeavesPerTask),
                      [&](const tbb::blocked_range<size_t>& run) {
        std::ifstream in(file.path, std::ios::in | std::ios::binary);
        if (!in) throw VdbReadError("cannot open " + vdb_reader::quoted(file.path) + ": " + std::strerror(errno));
        in.copyfmt(file.is);  // versions, compression, background, and throwing on a short read
        auto meta = std::make_shared<vdb::io::StreamMetadata>(*file.meta);
        vdb::io::setStreamMetadataPtr(in, meta, /*transfer=*/false);
        for (size_t i = run.begin(); i != run.end(); ++i) {
            if (i == run.begin() || numbers[i] != numbers[i - 1] + 1) in.seekg(positions[numbers[i]]);
            leaves[i]->readBuffers(in, half);
        }
    });
}

}  // namespace pcvr::vdb_reader
