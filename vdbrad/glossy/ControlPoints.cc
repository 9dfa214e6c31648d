#include "vdbrad/glossy/ControlPoints.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <utility>

namespace vdbrad {

using openvdb::math::Mat3d;
using openvdb::math::Vec3d;

namespace {

// Van Oosterom & Strackee: tan(E / 2) = [a b c] / (1 + a.b + b.c + c.a); a negative triple
// product (a point just outside by rounding) counts as no area.
double
area(const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    const double triple = a.dot(b.cross(c));
    return 2.0 * std::atan2(std::max(triple, 0.0), 1.0 + a.dot(b) + b.dot(c) + c.dot(a));
}

} // namespace

double
sphericalTriangleArea(const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    return 2.0 * std::atan2(std::abs(a.dot(b.cross(c))), 1.0 + a.dot(b) + b.dot(c) + c.dot(a));
}

int
ControlPoints::orderForCount(int count)
{
    for (int order = 0; order <= kMaxOrder; ++order) {
        if (count == 10 * (1 << (2 * order)) + 2) return order;
    }
    OPENVDB_THROW(openvdb::ValueError, "control points come in counts of 12, 42, 162, 642 or "
        "2562, got " << count);
}

ControlPoints::ControlPoints(int order) : mOrder(order)
{
    if (order < 0 || order > kMaxOrder) {
        OPENVDB_THROW(openvdb::ValueError, "control-point order must be in [0, " << kMaxOrder
            << "], got " << order);
    }
    // The icosahedron: cyclic permutations of (0, +-1, +-phi); its faces are the triples of
    // mutually adjacent vertices (edge length 2), oriented counter-clockwise from outside.
    const double phi = 0.5 * (1.0 + std::sqrt(5.0));
    for (const double s : {-1.0, 1.0}) {
        for (const double t : {-1.0, 1.0}) {
            mPoints.emplace_back(0.0, s, t * phi);
            mPoints.emplace_back(s, t * phi, 0.0);
            mPoints.emplace_back(t * phi, 0.0, s);
        }
    }
    std::vector<std::array<uint32_t, 3>> level;
    auto adjacent = [&](uint32_t a, uint32_t b) {
        return std::abs((mPoints[a] - mPoints[b]).length() - 2.0) < 1e-9;
    };
    for (uint32_t a = 0; a < 12; ++a) {
        for (uint32_t b = a + 1; b < 12; ++b) {
            for (uint32_t c = b + 1; c < 12; ++c) {
                if (!adjacent(a, b) || !adjacent(b, c) || !adjacent(a, c)) continue;
                const Vec3d n = (mPoints[b] - mPoints[a]).cross(mPoints[c] - mPoints[a]);
                if (n.dot(mPoints[a]) > 0.0) level.push_back({{a, b, c}});
                else level.push_back({{a, c, b}});
            }
        }
    }
    for (Vec3d& p : mPoints) p.normalize();
    mLevels.push_back(level);
    // Subdivision: corner children, then the middle one (locate() relies on this order).
    for (int k = 0; k < order; ++k) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoints;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            auto it = midpoints.find(key);
            if (it != midpoints.end()) return it->second;
            const uint32_t m = uint32_t(mPoints.size());
            mPoints.push_back((mPoints[a] + mPoints[b]).unit());
            midpoints.emplace(key, m);
            return m;
        };
        std::vector<std::array<uint32_t, 3>> next;
        next.reserve(level.size() * 4);
        for (const auto& t : level) {
            const uint32_t ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]),
                           ca = midpoint(t[2], t[0]);
            next.push_back({{t[0], ab, ca}});
            next.push_back({{ab, t[1], bc}});
            next.push_back({{ca, bc, t[2]}});
            next.push_back({{ab, bc, ca}});
        }
        level = std::move(next);
        mLevels.push_back(level);
    }
    mTriangles = level;

    mNeighbours.assign(mPoints.size(), {});
    for (const auto& t : mTriangles) {
        for (int e = 0; e < 3; ++e) {
            const uint32_t a = t[size_t(e)], b = t[size_t((e + 1) % 3)];
            mNeighbours[a].push_back(b);
            mNeighbours[b].push_back(a);
        }
    }
    for (size_t i = 0; i < mPoints.size(); ++i) {
        auto& n = mNeighbours[i];
        std::sort(n.begin(), n.end());
        n.erase(std::unique(n.begin(), n.end()), n.end());
        for (const uint32_t j : n) {
            mSpacing = std::max(mSpacing,
                std::acos(std::clamp(mPoints[i].dot(mPoints[j]), -1.0, 1.0)));
        }
    }

    // Areas: the integral of each point's weight, by a quadrature fine enough for 1e-6.
    mAreas.assign(mPoints.size(), 0.0);
    for (const Sample& q : quadrature(std::max(4, 32 >> order))) {
        for (int k = 0; k < 3; ++k) {
            mAreas[q.weights.index[size_t(k)]] += q.solidAngle * q.weights.weight[size_t(k)];
        }
    }
}

std::vector<ControlPoints::Sample>
ControlPoints::quadrature(int cuts) const
{
    if (cuts < 1 || cuts > 64) {
        OPENVDB_THROW(openvdb::ValueError, "quadrature cuts must be in [1, 64], got " << cuts);
    }
    const int s = cuts;
    std::vector<Sample> out;
    out.reserve(mTriangles.size() * size_t(s * s));
    for (const auto& t : mTriangles) {
        const Vec3d &A = mPoints[t[0]], &B = mPoints[t[1]], &C = mPoints[t[2]];
        auto at = [&](int u, int v) {   // lattice point (u, v) of the planar triangle
            return (A * double(s - u - v) + B * double(u) + C * double(v)).unit();
        };
        auto add = [&](const Vec3d& p, const Vec3d& q, const Vec3d& r) {
            Sample x;
            x.solidAngle = sphericalTriangleArea(p, q, r);
            x.direction = (p + q + r).unit();
            // The centre lies in t: its weights without a search.
            const double a0 = area(x.direction, B, C), a1 = area(x.direction, C, A),
                         a2 = area(x.direction, A, B);
            const double sum = a0 + a1 + a2;
            x.weights.index = t;
            x.weights.weight = {{a0 / sum, a1 / sum, a2 / sum}};
            out.push_back(x);
        };
        for (int u = 0; u < s; ++u) {
            for (int v = 0; u + v < s; ++v) {
                add(at(u, v), at(u + 1, v), at(u, v + 1));
                if (u + v + 1 < s) add(at(u + 1, v), at(u + 1, v + 1), at(u, v + 1));
            }
        }
    }
    return out;
}

uint32_t
ControlPoints::locate(const Vec3d& dir) const
{
    // Top level: the face whose three edge planes hold dir best (all >= 0 inside; on an edge,
    // rounding may leave every test slightly negative).
    uint32_t t = 0;
    double best = -1e300;
    const auto& top = mLevels[0];
    for (uint32_t f = 0; f < top.size(); ++f) {
        const Vec3d &a = mPoints[top[f][0]], &b = mPoints[top[f][1]], &c = mPoints[top[f][2]];
        const double m = std::min({dir.dot(a.cross(b)), dir.dot(b.cross(c)), dir.dot(c.cross(a))});
        if (m > best) { best = m; t = f; }
        if (m >= 0.0) break;
    }
    for (size_t k = 1; k < mLevels.size(); ++k) {
        const auto& children = mLevels[k];
        const uint32_t first = 4 * t;
        // The middle child's corners are the parent's edge midpoints: ab, bc, ca.
        const auto& mid = children[first + 3];
        const Vec3d &ab = mPoints[mid[0]], &bc = mPoints[mid[1]], &ca = mPoints[mid[2]];
        if (dir.dot(ab.cross(ca)) > 0.0) t = first;            // beyond ab-ca: corner a
        else if (dir.dot(bc.cross(ab)) > 0.0) t = first + 1;   // beyond bc-ab: corner b
        else if (dir.dot(ca.cross(bc)) > 0.0) t = first + 2;   // beyond ca-bc: corner c
        else t = first + 3;
    }
    return t;
}

ControlPoints::Weights
ControlPoints::weights(const Vec3d& dir) const
{
    const Vec3d p = dir.unit();
    const auto& t = mTriangles[locate(p)];
    const Vec3d &a = mPoints[t[0]], &b = mPoints[t[1]], &c = mPoints[t[2]];
    const double a0 = area(p, b, c), a1 = area(p, c, a), a2 = area(p, a, b);
    const double sum = a0 + a1 + a2;
    Weights w;
    w.index = t;
    if (sum > 0.0) {
        // Rounding leaves ~1e-16 on corners a direction at a control point does not touch:
        // dropped, so that maps between coinciding points are exact permutations.
        double b[3] = {a0 / sum, a1 / sum, a2 / sum};
        for (double& x : b) if (x < 1e-12) x = 0.0;
        const double total = b[0] + b[1] + b[2];
        w.weight = {{b[0] / total, b[1] / total, b[2] / total}};
    } else {
        // Only a direction on a corner itself can leave no area: that corner.
        const double d[3] = {p.dot(a), p.dot(b), p.dot(c)};
        const int k = int(std::max_element(d, d + 3) - d);
        w.weight = {{k == 0 ? 1.0 : 0.0, k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0}};
    }
    return w;
}

void
ControlPoints::deform(double* values, const Vec3d& dir, double delta) const
{
    const Weights w = weights(dir);
    const double norm = w.weight[0] * w.weight[0] + w.weight[1] * w.weight[1]
        + w.weight[2] * w.weight[2];
    for (int k = 0; k < 3; ++k) values[w.index[size_t(k)]] += w.weight[size_t(k)] * delta / norm;
}

Mat3d
ControlPoints::frame(const Vec3d& normal)
{
    const Vec3d n = normal.unit();
    // The x and y axes: a cyclic permutation of the axes (and two sign flips), which maps the
    // grid onto itself, so that the walls of voxelised boxes rotate without loss (Duff's frame
    // swaps two axes there, which does not). +-z: Duff's frame is already such a map.
    if (n.z() == 0.0 && (n.x() == 0.0 || n.y() == 0.0)) {
        const double s = n.x() + n.y();   // +-1
        Mat3d m = Mat3d::zero();
        if (n.x() != 0.0) {               // columns (0,1,0), (0,0,s), (s,0,0)
            m(1, 0) = 1.0; m(2, 1) = s; m(0, 2) = s;
        } else {                          // columns (0,0,1), (s,0,0), (0,s,0)
            m(2, 0) = 1.0; m(0, 1) = s; m(1, 2) = s;
        }
        return m;
    }
    const double sign = std::copysign(1.0, n.z());
    const double a = -1.0 / (sign + n.z());
    const double b = n.x() * n.y() * a;
    const Vec3d t(1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
    const Vec3d u(b, sign + n.y() * n.y() * a, -n.y());
    Mat3d m;
    for (int r = 0; r < 3; ++r) {
        m(r, 0) = t[r];
        m(r, 1) = u[r];
        m(r, 2) = n[r];
    }
    return m;
}

namespace {

/// A rotated point without a partner, or a real point without an owner.
constexpr uint32_t kFree = UINT32_MAX;

/// @throw openvdb::ValueError unless @a R is a proper rotation (orthonormal, det +1, to 1e-6)
void
checkRotation(const Mat3d& R)
{
    const Mat3d RtR = R.transpose() * R;
    double off = std::abs(R.det() - 1.0);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) off = std::max(off, std::abs(RtR(r, c) - (r == c ? 1.0 : 0.0)));
    }
    if (!(off <= 1e-6)) {
        OPENVDB_THROW(openvdb::ValueError, "not a proper rotation (orthonormality or determinant "
            "off by " << off << ")");
    }
}

/// Appends the row of real point @a i that interpolates f at R^T c_i (Resampled).
void
appendResampledRow(const ControlPoints& points, const Mat3d& R, size_t i, ControlPoints::Map& map)
{
    const ControlPoints::Weights w = points.weights(points.point(i) * R);
    for (int k = 0; k < 3; ++k) {
        if (w.weight[size_t(k)] == 0.0) continue;
        map.source.push_back(w.index[size_t(k)]);
        map.weight.push_back(float(w.weight[size_t(k)]));
    }
    map.start.push_back(uint32_t(map.source.size()));
}

/// @brief Appends every real point's row of the Continuous rotation: the weighted mean of what
/// the @a rotated points splat on it, or Resampled's row where nothing lands.
void
appendContinuousRows(const ControlPoints& points, const Mat3d& R,
    const std::vector<Vec3d>& rotated, ControlPoints::Map& map)
{
    const size_t n = points.size();
    std::vector<std::vector<std::pair<uint32_t, double>>> rows(n);
    for (size_t j = 0; j < n; ++j) {
        const ControlPoints::Weights w = points.weights(rotated[j]);
        for (int k = 0; k < 3; ++k) {
            if (w.weight[size_t(k)] > 0.0) {
                rows[w.index[size_t(k)]].emplace_back(uint32_t(j), w.weight[size_t(k)]);
            }
        }
    }
    for (size_t i = 0; i < n; ++i) {
        double total = 0.0;
        for (const auto& e : rows[i]) total += e.second;
        if (total <= 0.0) { appendResampledRow(points, R, i, map); continue; }
        for (const auto& e : rows[i]) {
            map.source.push_back(e.first);
            map.weight.push_back(float(e.second / total));
        }
        map.start.push_back(uint32_t(map.source.size()));
    }
}

/// @brief The candidate pairs (-cosine, rotated j, real i) within @a cosBound of each other;
/// @a near receives each rotated point's candidates, nearest first. @a mark and @a visit: the
/// walks' visited stamps, kept across calls.
std::vector<std::tuple<double, uint32_t, uint32_t>>
candidatePairs(const ControlPoints& points, const std::vector<Vec3d>& rotated, double cosBound,
    std::vector<std::vector<uint32_t>>& near, std::vector<uint32_t>& mark, uint32_t& visit)
{
    // Candidates: a walk over the real mesh from the nearest corner, within the bound.
    std::vector<std::tuple<double, uint32_t, uint32_t>> pairs;
    for (size_t j = 0; j < rotated.size(); ++j) {
        near[j].clear();
        const ControlPoints::Weights w = points.weights(rotated[j]);
        std::vector<uint32_t> stack(w.index.begin(), w.index.end());
        ++visit;
        for (const uint32_t i : stack) mark[i] = visit;
        while (!stack.empty()) {
            const uint32_t i = stack.back();
            stack.pop_back();
            const double d = rotated[j].dot(points.point(i));
            if (d < cosBound) continue;
            near[j].push_back(i);
            pairs.emplace_back(-d, uint32_t(j), i);
            for (const uint32_t k : points.neighbours(i)) {
                if (mark[k] != visit) { mark[k] = visit; stack.push_back(k); }
            }
        }
        std::sort(near[j].begin(), near[j].end(), [&](uint32_t a, uint32_t b) {
            return rotated[j].dot(points.point(a)) > rotated[j].dot(points.point(b));
        });
    }
    return pairs;
}

/// @brief Kuhn's augmenting paths (iterative DFS), nearest candidates first, for the rotated
/// points @a partner leaves free; whether every one found a partner among its @a near ones.
/// @a stamp and @a attempt: the searches' visited stamps, kept across calls.
bool
augmentPairs(const std::vector<std::vector<uint32_t>>& near, std::vector<uint32_t>& partner,
    std::vector<uint32_t>& owner, std::vector<uint32_t>& stamp, uint32_t& attempt)
{
    const size_t n = partner.size();
    bool complete = true;
    for (uint32_t j0 = 0; j0 < n && complete; ++j0) {
        if (partner[j0] != kFree) continue;
        ++attempt;
        std::vector<std::pair<uint32_t, size_t>> path{{j0, 0}};   // rotated point, next candidate
        bool found = false;
        while (!path.empty() && !found) {
            auto& [j, next] = path.back();
            if (next == near[j].size()) { path.pop_back(); continue; }
            const uint32_t i = near[j][next++];
            if (stamp[i] == attempt) continue;
            stamp[i] = attempt;
            if (owner[i] == kFree) {
                // Shift every pair along the path by one.
                uint32_t take = i;
                for (size_t k = path.size(); k-- > 0;) {
                    const uint32_t r = path[k].first, had = partner[r];
                    partner[r] = take;
                    owner[take] = r;
                    take = had;
                }
                found = true;
            } else {
                path.emplace_back(owner[i], 0);
            }
        }
        complete = found;
    }
    return complete;
}

/// @brief The Permutation's pairing: the real point of each of the @a rotated points. Pairs
/// closer than a bound, closest first, then augmenting paths for the rotated points left over;
/// the bound grows until every point is paired.
std::vector<uint32_t>
pairRotatedPoints(const ControlPoints& points, const std::vector<Vec3d>& rotated)
{
    const size_t n = points.size();
    std::vector<uint32_t> partner(n), owner(n);   // rotated j -> real i, real i -> rotated j
    std::vector<std::vector<uint32_t>> near(n);  // per rotated point, real points within the bound
    std::vector<uint32_t> mark(n, 0), stamp(n, 0);
    uint32_t visit = 0, attempt = 0;
    for (double bound = 0.6 * points.spacing();; bound *= 1.25) {
        const double cosBound = std::cos(std::min(bound, 3.2));
        std::vector<std::tuple<double, uint32_t, uint32_t>> pairs =
            candidatePairs(points, rotated, cosBound, near, mark, visit);
        std::sort(pairs.begin(), pairs.end());
        std::fill(partner.begin(), partner.end(), kFree);
        std::fill(owner.begin(), owner.end(), kFree);
        for (const auto& [d, j, i] : pairs) {
            if (partner[j] == kFree && owner[i] == kFree) { partner[j] = i; owner[i] = j; }
        }
        if (augmentPairs(near, partner, owner, stamp, attempt)) return partner;
    }
}

} // namespace

ControlPoints::Map
ControlPoints::rotation(const Mat3d& R, RotationKind kind) const
{
    checkRotation(R);
    const size_t n = size();
    Map map;
    map.start.assign(1, 0);

    if (kind == RotationKind::Resampled) {
        for (size_t i = 0; i < n; ++i) appendResampledRow(*this, R, i, map);
        return map;
    }

    std::vector<Vec3d> rotated(n);
    for (size_t j = 0; j < n; ++j) rotated[j] = R * mPoints[j];

    if (kind == RotationKind::Continuous) {
        appendContinuousRows(*this, R, rotated, map);
        return map;
    }

    const std::vector<uint32_t> partner = pairRotatedPoints(*this, rotated);
    std::vector<uint32_t> source(n);
    for (size_t j = 0; j < n; ++j) source[partner[j]] = uint32_t(j);
    for (size_t i = 0; i < n; ++i) {
        map.source.push_back(source[i]);
        map.weight.push_back(1.f);
        map.start.push_back(uint32_t(map.source.size()));
    }
    return map;
}

} // namespace vdbrad
