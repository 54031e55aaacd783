/// @file math.h
/// @brief Small double-precision vector and 4x4 matrix types for the rendering core.
///
/// Matrices use the column-vector convention of Blender and of the Python API:
/// `world = M * [i, j, k, 1]`, stored row-major (`m[row][col]`).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

namespace pcvr {

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3() = default;
    constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) { return std::sqrt(dot(a, a)); }
/// Two unit vectors completing the unit vector d to a right-handed orthonormal frame (e1, e2, d): e1 is
/// perpendicular to d and to the axis d is least aligned with, e2 = d x e1.
inline void complete_frame(const Vec3& d, Vec3& e1, Vec3& e2) {
    const Vec3 axis = std::abs(d.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    e1 = cross(axis, d) / length(cross(axis, d));
    e2 = cross(d, e1);
}

/// A rounded coordinate as an int, clamped to [lo, hi] first: a point projected from close to the
/// eye plane can lie far beyond int's range.
inline int clamp_to_int(double rounded, int lo, int hi) { return int(std::clamp(rounded, double(lo), double(hi))); }

struct Vec4 {
    double x = 0, y = 0, z = 0, w = 0;
};

struct Mat4 {
    double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};

    static Mat4 identity() { return Mat4(); }
    static Mat4 from_rows(const std::array<double, 16>& rowMajor);

    Mat4 operator*(const Mat4& o) const;
    Vec4 operator*(const Vec4& v) const;
    Vec3 transform_point(const Vec3& p) const;   ///< affine part only (ignores the last row)
    Vec3 transform_vector(const Vec3& v) const;  ///< upper-left 3x3 only
    Vec3 column(int c) const { return {m[0][c], m[1][c], m[2][c]}; }

    bool is_finite() const;
    bool is_affine() const;  ///< last row is (0, 0, 0, 1)
    /// Inverse, or nothing when the matrix is singular relative to its own scale (for an affine
    /// matrix, the scale of its 3x3 part: the translation does not count).
    std::optional<Mat4> inverse() const;
};

/// The largest singular value of the upper-left 3x3 block: how far a unit vector can be stretched.
double largest_singular_value(const Mat4& m);

}  // namespace pcvr
