/// @file fuzz_read_vdb.cpp
/// @brief libFuzzer target: any bytes as a .vdb file, through list_grids, read_vdb, the block view
/// and a small render of what was read, and through stream_vdb a batch per region.
///
/// Only pcvr errors (pcvr::Error) may come out: a crash, a sanitizer report, a hang, a leak or any
/// other exception is a finding. The seed corpus is written by native/fuzz/make_corpus.py.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "fuzz_scene.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/grid_stream.h"

namespace {

/// This process's scratch file (libFuzzer's workers are processes, so the pid keeps them apart).
const std::string& scratch_path() {
    static const std::string path = [] {
        const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        return std::string(dir) + "/pcvr_fuzz_" + std::to_string(getpid()) + ".vdb";
    }();
    return path;
}

bool write_file(const std::string& path, const uint8_t* data, size_t size) {
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return false;
    const bool ok = std::fwrite(data, 1, size, f) == size;
    return std::fclose(f) == 0 && ok;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string& path = scratch_path();
    if (!write_file(path, data, size)) return 0;
    try {
        for (const pcvr::GridInfo& info : pcvr::list_grids(path)) (void)info.name.size();
    } catch (const pcvr::Error&) {
    }
    try {
        const pcvr::Grid grid = pcvr::read_vdb(path);
        // Walking the blocks touches every voxel the renderer would; a render of what was read
        // exercises the transforms a file may carry.
        if (grid.active_voxel_count() <= pcvr::fuzz::kMaxRenderedVoxels) {
            (void)grid.blocks().size();
            pcvr::fuzz::render_framed(grid);
        }
    } catch (const pcvr::Error&) {
    }
    try {
        // Every leaf decoded from the offsets the layout walk recorded; the batches must hold exactly
        // the voxels the topology counts.
        const auto stream = pcvr::GridStream::open(path, "", 1);
        if (stream->active_voxel_count() <= pcvr::fuzz::kMaxRenderedVoxels) {
            uint64_t voxels = 0;
            stream->for_each_batch(1, [&](const pcvr::GridStream::Batch& batch) {
                (void)batch.grid.blocks().size();
                voxels = batch.voxels_done;
            });
            if (voxels != stream->active_voxel_count()) __builtin_trap();
        }
    } catch (const pcvr::Error&) {
    }
    return 0;
}
