// ControlPoints: functions on the sphere of directions given by their values at fixed points
// (Chatelier & Malgouyres, thesis 2006, §5.2): the representation of glossy voxels' radiance
// distributions and of BRDFs.
//
// Points: the 12 vertices of an icosahedron, each triangle split into four by its edge midpoints
// `order` times, every point projected onto the unit sphere: 12, 42, 162, 642, 2562 points for
// orders 0-4 (10 * 4^order + 2; the thesis found 162 a good default). A midpoint of a chord
// projects onto the great-circle arc of its edge, so a spherical triangle is tiled exactly by its
// four children: a direction is located by descending the subdivision, three plane tests per
// level (the thesis sorts points by parallels and meridians to find two candidate triangles; the
// descent is as cheap and needs no tolerance).
//
// Interpolation (§5.2.2): a direction P in the spherical triangle C1 C2 C3 has the weights
//     w_i = a_i / (a_1 + a_2 + a_3),   a_i = area of the spherical triangle P C_j C_k,
// (the spherical triangle's area by Van Oosterom and Strackee's formula), so the weights add up
// to 1 and a control point gets its own value back exactly. On an edge only its two corners
// weigh, but the two triangles sharing it split it a little differently (a spherical area is not
// linear in its corners): a jump below 0.2 % of the values' range at 162 points. A sweep
// direction's weights are the same for every voxel (§5.2.5): the solver computes them once per
// direction.
//
// Local deformation (§5.2.3): moving the interpolated value at P by d moves its corners by
// d_i = w_i d / sum_j w_j^2, the smallest change (in the least-squares sense) that does it.
//
// Rotation (§5.2.4): the values of g(w) = f(R^T w) on the same points, by
//   - Permutation: every rotated point R c_j is paired with one real point, which takes f's value
//     at c_j. Pairs are made closest first; a rotated point left without a free partner near it
//     takes one from a neighbour, which moves on to another (augmenting paths over the pairs
//     closer than a bound, raised until everyone is paired), so that no point is left with a
//     far-off partner (greedy pairing, globally or outwards through the mesh, strands a few
//     points at the end with partners across the sphere). Exact when R maps the grid onto
//     itself, lossy otherwise, and free to apply;
//   - Continuous: every rotated point R c_j splats f's value at c_j onto the real corners of the
//     triangle it lands in with its interpolation weights, and each real point takes the
//     weighted mean of what it receives (a point nothing lands on, interpolates f at R^T c_i);
//   - Resampled: each real point interpolates f at R^T c_i (the reference the others are
//     measured against; tests/test_control_points.cc).
// A rotation is a sparse linear map, so the solver precomputes one per normal that occurs.
#pragma once

#include <openvdb/math/Mat3.h>
#include <openvdb/math/Vec3.h>

#include <array>
#include <cstdint>
#include <vector>

namespace vdbrad {

class ControlPoints
{
public:
    /// Highest subdivision order (2562 points).
    static constexpr int kMaxOrder = 4;

    /// A direction's interpolation: the corners of its spherical triangle and their weights
    /// (adding up to 1).
    struct Weights
    {
        std::array<uint32_t, 3> index{{0, 0, 0}};
        std::array<double, 3> weight{{1.0, 0.0, 0.0}};
    };

    /// How a rotation is applied (see the file comment).
    enum class RotationKind { Permutation, Continuous, Resampled };

    /// A linear map of control values, out[i] = sum_e weight[e] in[source[e]] over the entries
    /// e in [start[i], start[i + 1]): a rotation, or any resampling.
    struct Map
    {
        std::vector<uint32_t> start;
        std::vector<uint32_t> source;
        std::vector<float> weight;
        size_t size() const { return start.empty() ? 0 : start.size() - 1; }
        template<typename T> void apply(const T* in, T* out) const
        {
            for (size_t i = 0; i + 1 < start.size(); ++i) {
                T v = T(0);
                for (uint32_t e = start[i]; e < start[i + 1]; ++e) v += T(weight[e]) * in[source[e]];
                out[i] = v;
            }
        }
    };

    /// @brief The points of an icosahedron subdivided @a order times.
    /// @throw openvdb::ValueError if @a order is outside [0, kMaxOrder]
    explicit ControlPoints(int order = 2);

    /// @brief The order whose point count is @a count (12, 42, 162, 642, 2562).
    /// @throw openvdb::ValueError for any other count
    static int orderForCount(int count);

    int order() const { return mOrder; }
    size_t size() const { return mPoints.size(); }
    const openvdb::math::Vec3d& point(size_t i) const { return mPoints[i]; }
    /// The spherical triangles of the finest level (corners counter-clockwise seen from outside).
    const std::vector<std::array<uint32_t, 3>>& triangles() const { return mTriangles; }
    /// Points sharing a triangle edge with point @a i.
    const std::vector<uint32_t>& neighbours(size_t i) const { return mNeighbours[i]; }
    /// Largest angle (radians) between a point and its neighbours: the grid's resolution.
    double spacing() const { return mSpacing; }

    /// @brief The interpolation weights of direction @a dir (need not be unit; not zero).
    Weights weights(const openvdb::math::Vec3d& dir) const;
    /// The finest triangle that holds @a dir (an index into triangles()).
    uint32_t locate(const openvdb::math::Vec3d& dir) const;

    /// The interpolated value of @a values (size() of them) at @a dir: the query.
    template<typename T>
    T evaluate(const T* values, const openvdb::math::Vec3d& dir) const
    {
        const Weights w = weights(dir);
        return T(w.weight[0]) * values[w.index[0]] + T(w.weight[1]) * values[w.index[1]]
            + T(w.weight[2]) * values[w.index[2]];
    }
    /// @brief Local deformation: change @a values so that the interpolated value at @a dir
    /// moves by @a delta, each corner by w_i delta / sum w_j^2.
    void deform(double* values, const openvdb::math::Vec3d& dir, double delta) const;

    /// @brief Solid angle each point stands for: the integral of its interpolation weight over
    /// the sphere (they add up to 4 pi), so that sum_i area_i f_i integrates the interpolated f
    /// exactly (up to the quadrature of the weights, 1e-6).
    const std::vector<double>& areas() const { return mAreas; }

    /// A direction, the solid angle it stands for, and its interpolation.
    struct Sample
    {
        openvdb::math::Vec3d direction;
        double solidAngle = 0.0;
        Weights weights;
    };
    /// @brief A quadrature of the sphere: every finest triangle cut into @a cuts^2 small
    /// spherical triangles (which tile it exactly: the solid angles add up to 4 pi to rounding),
    /// each sampled at its centre. For fitting functions to the points (ControlBrdf.h).
    /// @throw openvdb::ValueError unless 1 <= @a cuts <= 64
    std::vector<Sample> quadrature(int cuts) const;

    /// @brief The map taking the values of f to those of g(w) = f(R^T w), for a proper rotation
    /// @a R (applied to column vectors: w' = R w, OpenVDB's R * w; R^T w is w * R).
    /// @throw openvdb::ValueError if @a R is not a rotation (orthonormal, det +1, to 1e-6)
    Map rotation(const openvdb::math::Mat3d& R, RotationKind kind) const;

    /// @brief A right-handed orthonormal frame whose third column is the unit @a normal:
    /// world = frame * local (Duff et al. 2017). For the six axis normals it maps the grid onto
    /// itself, so that rotations into the frames of axis-aligned walls are exact permutations.
    static openvdb::math::Mat3d frame(const openvdb::math::Vec3d& normal);

private:
    int mOrder;
    std::vector<openvdb::math::Vec3d> mPoints;
    std::vector<std::array<uint32_t, 3>> mTriangles;        // finest level
    // Descent: the triangles of every level; a level's triangle t has children 4t..4t+3 in the
    // next (corner children 0-2, then the middle one).
    std::vector<std::vector<std::array<uint32_t, 3>>> mLevels;
    std::vector<std::vector<uint32_t>> mNeighbours;
    std::vector<double> mAreas;
    double mSpacing = 0.0;
};

/// Area of the spherical triangle of the unit vectors @a a, @a b, @a c (steradians, >= 0).
double sphericalTriangleArea(const openvdb::math::Vec3d& a, const openvdb::math::Vec3d& b,
    const openvdb::math::Vec3d& c);

} // namespace vdbrad
