// Classification tables (pcvr/transfer_function.h): interpolation, opacity correction, transparency.
#include <cmath>

#include "pcvr/errors.h"
#include "pcvr/transfer_function.h"
#include "unit_test.h"

using namespace pcvr;

namespace {
TransferFunction ramp() {
    TransferFunction tf;
    tf.density = {0.0, 0.3, 0.6, 1.0};
    tf.rgba = {{0, 0, 0, 0}, {0.8, 0.4, 0.3, 0.0}, {0.9, 0.8, 0.6, 0.4}, {1, 1, 1, 0.9}};
    return tf;
}
}  // namespace

TEST(classification_interpolates_the_control_points_and_corrects_opacity) {
    const double unit = 0.5;
    const ClassificationTable table(ramp(), unit);
    for (double d : {0.6, 0.7, 0.85, 1.0}) {
        const auto s = table(float(d));
        // Linear between control points: at 0.85, halfway from (0.9, 0.8, 0.6, 0.4) to (1, 1, 1, 0.9).
        const double t = std::clamp((d - 0.6) / 0.4, 0.0, 1.0);
        CHECK_NEAR(s.red, 0.9 + t * 0.1, 1e-3);
        CHECK_NEAR(s.blue, 0.6 + t * 0.4, 1e-3);
        const double opacity = 0.4 + t * 0.5;
        // A slab of the unit distance has the control points' opacity.
        CHECK_NEAR(1.0 - std::exp(-double(s.extinction) * unit), opacity, 1e-3);
    }
    CHECK(table(-5.0f).extinction == 0.0f && table(0.2f).extinction == 0.0f);
    CHECK(table(100.0f).red == table(1.0f).red);  // beyond the last point: its values
}

TEST(classification_knows_its_transparent_ranges) {
    const ClassificationTable table(ramp(), 1.0);
    CHECK(table.transparent(-10.0, 0.29));
    CHECK(!table.transparent(0.0, 0.31));
    CHECK(!table.transparent(0.5, 0.6));
    // maybe_opaque is false only where every density has zero opacity.
    for (int i = -100; i <= 300; ++i) {
        const float d = i * 0.005f;
        if (!lane_mask(table.maybe_opaque(broadcast8(d)))) CHECK(table(d).extinction == 0.0f);
    }
}

TEST(transfer_functions_refuse_what_they_cannot_mean) {
    auto refused = [](TransferFunction tf) {
        try {
            tf.validate();
        } catch (const InvalidArgument&) {
            return true;
        }
        return false;
    };
    TransferFunction unsorted = ramp();
    unsorted.density[2] = 0.2;
    TransferFunction too_opaque = ramp();
    too_opaque.rgba[3][3] = 1.5;
    TransferFunction empty;
    CHECK(refused(unsorted) && refused(too_opaque) && refused(empty));
    CHECK(!refused(ramp()));
}

TEST(emitting_densities_are_visible_without_opacity) {
    TransferFunction tf;
    tf.density = {0.0, 0.4, 1.0};
    tf.rgba = {{0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}};  // no opacity anywhere
    tf.emission = {{0, 0, 0}, {0, 0, 0}, {2, 1, 0.5}};
    const ClassificationTable table(tf, 1.0);
    CHECK(table.has_emission());
    CHECK_NEAR(table.emission(0.7f).red, 1.0, 1e-3);  // halfway from 0 to 2
    CHECK_NEAR(table.emission(0.7f).blue, 0.25, 1e-3);
    CHECK(table.emission(5.0f).green == table.emission(1.0f).green);
    // Transparent only below the first emitting density; maybe_opaque lets every emitting sample through.
    CHECK(table.transparent(-1.0, 0.39));
    CHECK(!table.transparent(0.3, 0.41));
    for (int i = -100; i <= 300; ++i) {
        const float d = i * 0.005f;
        if (!lane_mask(table.maybe_opaque(broadcast8(d)))) CHECK(table.emission(d).red == 0.0f);
    }
    TransferFunction short_emission = tf;
    short_emission.emission.pop_back();
    TransferFunction negative = tf;
    negative.emission[1][2] = -0.1;
    int refused = 0;
    for (const TransferFunction* bad : {&short_emission, &negative}) {
        try {
            bad->validate();
        } catch (const InvalidArgument&) {
            refused += 1;
        }
    }
    CHECK(refused == 2);
}
