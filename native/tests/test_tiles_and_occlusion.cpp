// Tiles, sheet rings and occlusion maps: the bookkeeping of the sheet walk (src/view/tile_set.h,
// src/shaded/sheets/sheet_buffer.h, src/shaded/sheets/occlusion_map.h).
#include <random>

#include "shaded/sheets/occlusion_map.h"
#include "shaded/sheets/sheet_buffer.h"
#include "unit_test.h"
#include "view/tile_set.h"

using namespace pcvr;

TEST(tile_set_lists_a_block_in_every_tile_it_reaches_nearest_first) {
    TileSet tiles(300, 200, 128);  // 3 x 2 tiles, the last column and row partial
    CHECK(tiles.size() == 6);
    CHECK(tiles.rect(5).x0 == 256 && tiles.rect(5).x1 == 300 && tiles.rect(5).y1 == 200);
    tiles.add(0, 7, 5.0, 120.0, 10.0, 140.0, 20.0, 0.0);   // straddles tiles 0 and 1
    tiles.add(0, 3, 2.0, 130.0, 130.0, 131.0, 131.0, 0.0); // tile 4 only
    tiles.add(1, 1, 1.0, 129.0, 5.0, 129.5, 6.0, 2.0);     // tile 1, and tile 0 through its reach
    tiles.sort();
    CHECK(tiles.blocks(0).size() == 2 && tiles.blocks(0)[0].layer == 1 && tiles.blocks(0)[1].block == 7);
    CHECK(tiles.blocks(1).size() == 2 && tiles.blocks(1)[0].front == 1.0);
    CHECK(tiles.blocks(4).size() == 1 && tiles.blocks(2).empty());
    CHECK(tiles.blocks(0)[1].min_x == 120.0f);  // bounds without the reach
}

TEST(sheet_ring_reuses_slots_and_zeroes_only_what_was_touched) {
    SheetRing ring;
    ring.reset(20, 10, 5);
    CHECK(ring.depth() == 8);  // a power of two
    for (int64_t s = -3; s < 20; ++s) {
        float* sheet = ring.sheet(s);
        CHECK(ring.touched(s).empty());
        sheet[3 * ring.pitch() + 4] = 1.0f;
        ring.touch(s, {4, 3, 4, 3});
        CHECK(ring.sheet(s + 8) == sheet && ring.sheet(s - 8) == sheet);
        ring.release(s);
        CHECK(sheet[3 * ring.pitch() + 4] == 0.0f);
    }
}

TEST(occlusion_map_matches_a_brute_force_test) {
    std::mt19937 rng(7);
    const int w = 37, h = 29, stride = 3, columns = 18, rows = 15, reach = 4, ox = 5, oy = 4;
    std::vector<uint8_t> opaque(w * h);
    for (auto& o : opaque) o = rng() % 10 < 8;
    OpenPixels open;
    open.count(w, h, [&](int x, int y) { return opaque[y * w + x] != 0; });
    OcclusionMap map;
    map.rebuild(open, stride, ox, oy, columns, rows, reach);
    auto node_occluded = [&](int c, int r) {
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                if (std::abs(x - (stride * c - ox)) <= reach && std::abs(y - (stride * r - oy)) <= reach && !opaque[y * w + x])
                    return false;
        return true;
    };
    for (int trial = 0; trial < 300; ++trial) {
        const int c0 = rng() % columns, r0 = rng() % rows;
        const int c1 = std::min(columns - 1, c0 + int(rng() % 4)), r1 = std::min(rows - 1, r0 + int(rng() % 4));
        bool all = true;
        for (int r = r0; r <= r1; ++r)
            for (int c = c0; c <= c1; ++c) all &= node_occluded(c, r);
        CHECK(map.covered(c0, r0, c1, r1) == all);
    }
}
