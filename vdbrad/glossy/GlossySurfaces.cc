#include "vdbrad/glossy/GlossySurfaces.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/TextFormat.h"

#include <openvdb/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <sstream>
#include <tuple>

namespace vdbrad {

using openvdb::math::Vec3d;

struct GlossySurfaces::Class
{
    uint32_t lobe = 0;
    Vec3d normal;
    ControlPoints::Map Q;         // local values -> world values
    std::vector<double> d;        // the symmetric scaling D_c
    std::vector<double> share;    // h_c: the direction set's cosine weights on the points
    std::vector<float> exitance;  // e_c = h_c / sum h_c
    // Harmonics: D_c and D_c^T, and the normalisation for the full hemisphere's h_c.
    SphericalHarmonics::Rotation toWorld, toLocal;
    Normaliser norm;
};

const char*
glossyBasisName(GlossyBasis basis)
{
    return basis == GlossyBasis::Harmonics ? "harmonics" : "points";
}

namespace {


template<typename T> struct Channels { static constexpr bool kRgb = false; };
template<> struct Channels<openvdb::Vec3f> { static constexpr bool kRgb = true; };
template<> struct Channels<openvdb::Vec3d> { static constexpr bool kRgb = true; };

template<typename T> T channel(T v, int) { return v; }
template<typename S> S channel(const openvdb::math::Vec3<S>& v, int ch) { return v[ch]; }

/// @brief The rotation @a Q (local values to world values) with its sources numbered as slots of
/// the lobe's @a support, where the kernel's product works.
ControlPoints::Map
onSupport(const ControlPoints::Map& Q, const std::vector<uint32_t>& support)
{
    // Sources as slots of the lobe's support; other local points carry nothing.
    const size_t P = Q.size();
    std::vector<uint32_t> slot(P, UINT32_MAX);
    for (size_t j = 0; j < support.size(); ++j) slot[support[j]] = uint32_t(j);
    ControlPoints::Map q;
    q.start.push_back(0);
    for (size_t i = 0; i < P; ++i) {
        for (uint32_t e = Q.start[i]; e < Q.start[i + 1]; ++e) {
            if (slot[Q.source[e]] == UINT32_MAX) continue;
            q.source.push_back(slot[Q.source[e]]);
            q.weight.push_back(Q.weight[e]);
        }
        q.start.push_back(uint32_t(q.source.size()));
    }
    return q;
}

} // namespace

template<typename T>
void
GlossySurfaces::product(const Class& c, const T* in, T* out, std::vector<Scalar<T>>& a,
    std::vector<Scalar<T>>& b) const
{
    // out = Q K Q^T in: Q^T moves the world values to the lobe's support (c.Q's sources are
    // support slots), K is one dense product there (ControlBrdf::apply), Q moves them back.
    // D_c is applied by the callers. Channels are the columns of a and b.
    constexpr int W = Channels<T>::kRgb ? 3 : 1;
    const size_t P = points(), s = mLobes[c.lobe]->support().size();
    const ControlPoints::Map& Q = c.Q;
    a.assign(s * W, Scalar<T>(0));
    b.resize(s * W);
    for (size_t i = 0; i < P; ++i) {
        for (uint32_t e = Q.start[i]; e < Q.start[i + 1]; ++e) {
            const Scalar<T> w = Scalar<T>(Q.weight[e]);
            for (int ch = 0; ch < W; ++ch) a[size_t(ch) * s + Q.source[e]] += channel(in[i], ch) * w;
        }
    }
    mLobes[c.lobe]->apply(a.data(), b.data(), W);
    for (size_t i = 0; i < P; ++i) {
        Scalar<T> v[W] = {};
        for (uint32_t e = Q.start[i]; e < Q.start[i + 1]; ++e) {
            const Scalar<T> w = Scalar<T>(Q.weight[e]);
            for (int ch = 0; ch < W; ++ch) v[ch] += w * b[size_t(ch) * s + Q.source[e]];
        }
        if constexpr (W == 3) out[i] = T(v[0], v[1], v[2]);
        else out[i] = v[0];
    }
}

GlossySurfaces::GlossySurfaces(const Scene& scene, const DirectionSet& directions,
    const GlossyOptions& options)
    : mOptions(options)
    , mPoints(ControlPoints::orderForCount(options.controlPoints))
    , mScene(scene)
{
    const auto t0 = std::chrono::steady_clock::now();
    if (options.basis == GlossyBasis::Harmonics) {
        if (options.harmonicOrder < 1 || options.harmonicOrder > SphericalHarmonics::kMaxOrder) {
            OPENVDB_THROW(openvdb::ValueError, "harmonic order " + std::to_string(
                options.harmonicOrder) + " is outside 1.." + std::to_string(
                SphericalHarmonics::kMaxOrder));
        }
        mHarmonics.reset(new SphericalHarmonics(options.harmonicOrder));
    }
    mValues = mHarmonics ? mHarmonics->size() : mPoints.size();
    findGlossyVoxels(scene);
    findClasses(scene, fitLobes(scene));
    if (mHarmonics) setupHarmonics(directions);
    else setupPoints(directions);
    mSetupSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void
GlossySurfaces::findGlossyVoxels(const Scene& scene)
{
    const size_t n = scene.size();
    mGlossyOf.assign(n, kNone);
    for (size_t i = 0; i < n; ++i) {
        const openvdb::Vec3f ks = scene.specular().rgb(i);
        if (ks[0] > 0.f || ks[1] > 0.f || ks[2] > 0.f) {
            mGlossyOf[i] = uint32_t(mVoxel.size());
            mVoxel.push_back(uint32_t(i));
        }
    }
}

std::vector<uint32_t>
GlossySurfaces::fitLobes(const Scene& scene)
{
    // Lobes: one kernel per rounded roughness.
    std::map<long, uint32_t> lobeOf;
    std::vector<uint32_t> lobe(mVoxel.size());
    std::vector<double> roughness;
    for (size_t g = 0; g < mVoxel.size(); ++g) {
        const long key = roughnessKey(scene.roughness().grey(mVoxel[g]));
        auto it = lobeOf.emplace(key, uint32_t(roughness.size())).first;
        if (it->second == roughness.size()) roughness.push_back(roughnessOf(key));
        lobe[g] = it->second;
    }
    if (mHarmonics) {
        mHarmonicLobes.resize(roughness.size());
        for (size_t l = 0; l < roughness.size(); ++l) {
            mHarmonicLobes[l].reset(new HarmonicBrdf(*mHarmonics,
                Brdf(mOptions.model, roughness[l])));
        }
    } else {
        mLobes.resize(roughness.size());
        tbb::parallel_for(size_t(0), roughness.size(), [&](size_t l) {
            mLobes[l].reset(new ControlBrdf(mPoints, Brdf(mOptions.model, roughness[l]),
                mOptions.fit));
        });
    }
    return lobe;
}

void
GlossySurfaces::findClasses(const Scene& scene, const std::vector<uint32_t>& lobe)
{
    // Classes: (normal, lobe), the normals exact while few enough, else rounded to a fine grid.
    auto keyOf = [&](const openvdb::Vec3f& nrm, uint32_t l) {
        uint32_t b[3];
        std::memcpy(b, nrm.asPointer(), sizeof b);
        return std::make_tuple(b[0], b[1], b[2], l);
    };
    std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, uint32_t> classOf;
    std::vector<Vec3d> normalOf(mVoxel.size());
    for (size_t g = 0; g < mVoxel.size(); ++g) {
        normalOf[g] = Vec3d(scene.normal(mVoxel[g]));
        classOf.emplace(keyOf(scene.normal(mVoxel[g]), lobe[g]), 0);
    }
    if (classOf.size() > kMaxClasses) {
        const ControlPoints fine(ControlPoints::kMaxOrder);
        for (size_t g = 0; g < mVoxel.size(); ++g) {
            const ControlPoints::Weights w = fine.weights(normalOf[g]);
            const int k = int(std::max_element(w.weight.begin(), w.weight.end())
                - w.weight.begin());
            normalOf[g] = fine.point(w.index[size_t(k)]);
        }
    }
    classOf.clear();
    mClassOf.resize(mVoxel.size());
    for (size_t g = 0; g < mVoxel.size(); ++g) {
        auto it = classOf.emplace(keyOf(openvdb::Vec3f(normalOf[g]), lobe[g]),
            uint32_t(mClasses.size())).first;
        if (it->second == mClasses.size()) {
            mClasses.emplace_back();
            mClasses.back().lobe = lobe[g];
            mClasses.back().normal = normalOf[g].unit();
        }
        mClassOf[g] = it->second;
    }
}

void
GlossySurfaces::setupHarmonics(const DirectionSet& directions)
{
    const size_t P = mValues;
    mHarmonicToward.resize(2 * directions.size() * P);
    std::vector<double> y(P);
    for (size_t k = 0; k < 2 * directions.size(); ++k) {
        mHarmonics->basis(directions.unit(k / 2) * (k % 2 ? -1.0 : 1.0), y.data());
        for (size_t b = 0; b < P; ++b) mHarmonicToward[k * P + b] = float(y[b]);
    }
    tbb::parallel_for(size_t(0), mClasses.size(), [&](size_t ci) {
        setupHarmonicClass(mClasses[ci], directions);
    });
    mVoxelNorm.resize(mVoxel.size());
}

void
GlossySurfaces::setupPoints(const DirectionSet& directions)
{
    const size_t P = mValues;
    mToward.resize(2 * directions.size());
    for (size_t k = 0; k < directions.size(); ++k) {
        mToward[2 * k] = mPoints.weights(directions.unit(k));
        mToward[2 * k + 1] = mPoints.weights(-directions.unit(k));
    }

    tbb::parallel_for(size_t(0), mClasses.size(), [&](size_t ci) {
        setupPointClass(mClasses[ci], directions);
    });

    mInvShare.assign(mVoxel.size() * P, 0.f);
    for (size_t g = 0; g < mVoxel.size(); ++g) setShare(g, nullptr);
}

void
GlossySurfaces::setupPointClass(Class& c, const DirectionSet& directions) const
{
    const size_t P = mValues;
    c.Q = onSupport(mPoints.rotation(ControlPoints::frame(c.normal), mOptions.rotation),
        mLobes[c.lobe]->support());
    // h_c: the cosine weights of the set's directions on this normal's hemisphere, splatted
    // as the sweeps splat light.
    c.share.assign(P, 0.0);
    for (size_t k = 0; k < directions.size(); ++k) {
        const double cosine = directions.unit(k).dot(c.normal);
        if (cosine == 0.0) continue;
        const ControlPoints::Weights& w = toward(k, cosine < 0.0);
        const double weight = std::abs(cosine) * directions.factor(k);
        for (int j = 0; j < 3; ++j) c.share[w.index[size_t(j)]] += weight * w.weight[size_t(j)];
    }
    double total = 0.0;
    for (const double h : c.share) total += h;
    c.exitance.resize(P);
    for (size_t i = 0; i < P; ++i) c.exitance[i] = float(c.share[i] / total);
    scaleSymmetrically(c);
}

void
GlossySurfaces::scaleSymmetrically(Class& c) const
{
    // Symmetric Sinkhorn: d <- sqrt(d / (K_c (d h))) until d (K_c (d h)) = 1 on the rows
    // uniform light reaches.
    const size_t P = mValues;
    std::vector<double> x(P), y(P), a, b;
    product(c, c.share.data(), y.data(), a, b);
    c.d.assign(P, 0.0);
    for (size_t i = 0; i < P; ++i) c.d[i] = y[i] > 0.0 ? 1.0 / std::sqrt(y[i]) : 0.0;
    for (int it = 0; it < 1000; ++it) {
        for (size_t i = 0; i < P; ++i) x[i] = c.d[i] * c.share[i];
        product(c, x.data(), y.data(), a, b);
        double worst = 0.0;
        for (size_t i = 0; i < P; ++i) {
            if (c.d[i] == 0.0) continue;
            worst = std::max(worst, std::abs(c.d[i] * y[i] - 1.0));
            c.d[i] = y[i] > 0.0 ? std::sqrt(c.d[i] / y[i]) : 0.0;
        }
        if (worst < 1e-7) break;   // the kernel is float
    }
}

GlossySurfaces::~GlossySurfaces() = default;

void
GlossySurfaces::normalise(const Class& c, std::vector<double> h, Normaliser& norm) const
{
    // u . h = sqrt(4 pi) Y_00 sum w = sum w.
    const size_t N = mValues;
    norm.h = std::move(h);
    norm.z = std::sqrt(4.0 * kPi) * norm.h[0];
    norm.q.assign(N, 0.0);
    norm.hh = norm.qh = 0.0;
    std::vector<double> y(N);
    reflectHarmonicRaw(c, norm, norm.h.data(), y.data());   // no correction yet: q = 0
    norm.q[0] = std::sqrt(4.0 * kPi);
    for (size_t b = 0; b < N; ++b) {
        norm.q[b] -= y[b];
        norm.hh += norm.h[b] * norm.h[b];
        norm.qh += norm.q[b] * norm.h[b];
    }
}

void
GlossySurfaces::setupHarmonicClass(Class& c, const DirectionSet& directions) const
{
    const size_t N = mValues;
    const openvdb::math::Mat3d R = ControlPoints::frame(c.normal);
    c.toWorld = mHarmonics->rotation(R);
    c.toLocal = mHarmonics->rotation(R.transpose());
    // h_c as the sweeps splat: Y of the sense facing the normal, times its cosine weight.
    c.share.assign(N, 0.0);
    for (size_t k = 0; k < directions.size(); ++k) {
        const double cosine = directions.unit(k).dot(c.normal);
        if (cosine == 0.0) continue;
        const float* y = harmonicToward(k, cosine < 0.0);
        const double weight = std::abs(cosine) * directions.factor(k);
        for (size_t b = 0; b < N; ++b) c.share[b] += weight * double(y[b]);
    }
    normalise(c, c.share, c.norm);
    c.exitance.resize(N);
    for (size_t b = 0; b < N; ++b) c.exitance[b] = float(c.share[b] / c.norm.z);
}

void
GlossySurfaces::reflectHarmonicRaw(const Class& c, const Normaliser& norm, const double* in,
    double* out) const
{
    // out = (D K D^T in) / Z + Delta in (Delta: 0 while q is).
    const size_t N = mValues;
    std::vector<double> a(N), b(N);
    c.toLocal.apply(in, a.data());
    mHarmonicLobes[c.lobe]->apply(a.data(), b.data(), 1);
    c.toWorld.apply(b.data(), out);
    double hx = 0.0, qx = 0.0;
    for (size_t i = 0; i < N; ++i) {
        out[i] /= norm.z;
        hx += norm.h[i] * in[i];
        qx += norm.q[i] * in[i];
    }
    if (norm.hh > 0.0) {
        const double s = 1.0 / norm.hh, t = norm.qh * hx * s * s;
        for (size_t i = 0; i < N; ++i) {
            out[i] += (norm.q[i] * hx + norm.h[i] * qx) * s - t * norm.h[i];
        }
    }
}

size_t GlossySurfaces::classes() const { return mClasses.size(); }

double
GlossySurfaces::roughnessOf(long key)
{
    return std::clamp(double(key) * kRoughnessStep, Brdf::kMinRoughness, 1.0);
}

std::vector<uint32_t>
GlossySurfaces::splatPoints(const ControlPoints& points, const DirectionSet& directions,
    const std::vector<size_t>& ks)
{
    std::vector<char> used(points.size(), 0);
    for (const size_t k : ks) {
        for (const double sense : {1.0, -1.0}) {
            for (const uint32_t i : points.weights(directions.unit(k) * sense).index) used[i] = 1;
        }
    }
    std::vector<uint32_t> out;
    for (size_t i = 0; i < used.size(); ++i) {
        if (used[i]) out.push_back(uint32_t(i));
    }
    return out;
}

void
GlossySurfaces::setShare(size_t g, const double* share)
{
    const size_t P = points();
    const Class& c = mClasses[mClassOf[g]];
    if (!share) share = c.share.data();
    if (mHarmonics) {
        const double z = std::sqrt(4.0 * kPi) * share[0];
        if (share != c.share.data() && z > 1e-6 * c.norm.z) {
            double dev = 0.0;
            for (size_t i = 0; i < P; ++i) dev = std::max(dev, std::abs(share[i] - c.share[i]));
            if (dev == 0.0) share = c.share.data();   // nothing missed: the class's
        }
        if (share == c.share.data() || !(z > 1e-6 * c.norm.z)) {
            // Open to the sky (or nothing measured): the class's normalisation.
            mVoxelNorm[g].reset();
            return;
        }
        auto norm = std::make_unique<Normaliser>();
        normalise(c, std::vector<double>(share, share + P), *norm);
        mVoxelNorm[g] = std::move(norm);
        return;
    }
    std::vector<double> x(P), r(P), a, b;
    for (size_t i = 0; i < P; ++i) x[i] = c.d[i] * share[i];
    product(c, x.data(), r.data(), a, b);
    double peak = 0.0;
    for (size_t i = 0; i < P; ++i) peak = std::max(peak, c.d[i] * r[i]);
    float* inv = &mInvShare[g * P];
    for (size_t i = 0; i < P; ++i) {
        const double v = c.d[i] * r[i];
        inv[i] = v > 1e-6 * peak ? float(1.0 / v) : 0.f;
    }
}

template<typename T>
void
GlossySurfaces::reflect(size_t g, const T* incident, T* out) const
{
    if (mHarmonics) {
        reflectHarmonic(g, incident, out);
        return;
    }
    const size_t P = points();
    const Class& c = mClasses[mClassOf[g]];
    std::vector<T> x(P);
    std::vector<Scalar<T>> a, b;
    for (size_t i = 0; i < P; ++i) x[i] = incident[i] * c.d[i];
    product(c, x.data(), out, a, b);
    const float* inv = &mInvShare[g * P];
    const size_t v = mVoxel[g];
    if constexpr (Channels<T>::kRgb) {
        const openvdb::Vec3f ks = mScene.specular().rgb(v);
        for (size_t i = 0; i < P; ++i) {
            const double s = c.d[i] * inv[i];
            for (int ch = 0; ch < 3; ++ch) out[i][ch] *= typename T::ValueType(ks[ch] * s);
        }
    } else {
        const double ks = mScene.specular().grey(v);
        for (size_t i = 0; i < P; ++i) out[i] *= T(ks * c.d[i] * inv[i]);
    }
}

template<typename T>
void
GlossySurfaces::reflectHarmonic(size_t g, const T* incident, T* out) const
{
    // Channel by channel in double: the rotations' blocks are double, and a reflection costs
    // ~N^2 (6,561 products at L = 8) against a sweep's N per direction.
    constexpr int W = Channels<T>::kRgb ? 3 : 1;
    const size_t N = points();
    const Class& c = mClasses[mClassOf[g]];
    const size_t v = mVoxel[g];
    const openvdb::Vec3f ks = mScene.specular().rgb(v);
    std::vector<double> x(N), y(N);
    for (int ch = 0; ch < W; ++ch) {
        for (size_t i = 0; i < N; ++i) x[i] = double(channel(incident[i], ch));
        reflectHarmonicRaw(c, mVoxelNorm[g] ? *mVoxelNorm[g] : c.norm, x.data(), y.data());
        const double s = W == 3 ? double(ks[ch]) : mScene.specular().grey(v);
        for (size_t i = 0; i < N; ++i) {
            if constexpr (W == 3) out[i][ch] = typename T::ValueType(y[i] * s);
            else out[i] = T(y[i] * s);
        }
    }
}

void
GlossySurfaces::splat(const Vec3d& dir, const openvdb::Vec3f& value, openvdb::Vec3f* out) const
{
    if (mHarmonics) {
        std::vector<double> y(mValues);
        mHarmonics->basis(dir, y.data());
        for (size_t b = 0; b < mValues; ++b) out[b] += value * float(y[b]);
        return;
    }
    const ControlPoints::Weights w = mPoints.weights(dir);
    for (int j = 0; j < 3; ++j) out[w.index[size_t(j)]] += value * float(w.weight[size_t(j)]);
}

template<typename T>
T
GlossySurfaces::evaluate(const T* S, const Vec3d& dir) const
{
    if (!mHarmonics) return mPoints.evaluate(S, dir);
    std::vector<double> y(mValues);
    mHarmonics->basis(dir, y.data());
    T sum(0);
    for (size_t b = 0; b < mValues; ++b) sum += S[b] * Scalar<T>(y[b]);
    return sum;
}

template<typename T>
T
GlossySurfaces::exitance(size_t g, const T* S) const
{
    const Class& c = mClasses[mClassOf[g]];
    T sum(0);
    for (size_t i = 0; i < points(); ++i) sum += S[i] * c.exitance[i];
    return sum;
}

size_t
GlossySurfaces::memUsage() const
{
    const size_t P = points();
    size_t bytes = (mGlossyOf.capacity() + mVoxel.capacity() + mClassOf.capacity()) * 4
        + mInvShare.capacity() * 4 + mToward.capacity() * sizeof(ControlPoints::Weights);
    // Each kernel: full (float) and over its support (float and double).
    for (const auto& l : mLobes) {
        bytes += l->kernel().capacity() * 4 + l->support().size() * l->support().size() * 12;
    }
    for (const Class& c : mClasses) {
        bytes += c.Q.source.capacity() * 8 + c.Q.start.capacity() * 4 + P * (8 + 8 + 4);
    }
    if (mHarmonics) {
        bytes += mHarmonicToward.capacity() * 4 + mHarmonicLobes.size() * P * P * 12;
        // Per class: two rotations' blocks (~L^3 values each), h_c, q.
        const size_t blocks = SphericalHarmonics::Rotation::blockOffset(mHarmonics->order() + 1);
        bytes += mClasses.size() * (2 * blocks + 2 * P) * 8;
        for (const auto& norm : mVoxelNorm) bytes += norm ? (2 * P + 3) * 8 : 0;
    }
    return bytes;
}

std::string
GlossySurfaces::describe() const
{
    std::ostringstream os;
    os << withCommas(size()) << " glossy voxels (" << brdfModelName(mOptions.model) << ", ";
    if (mHarmonics) os << "harmonics of order " << mHarmonics->order() << ", ";
    else os << points() << " control points, ";
    os << lobes() << (lobes() == 1 ? " lobe, " : " lobes, ")
       << classes() << (classes() == 1 ? " normal class)" : " normal classes)");
    return os.str();
}

template void GlossySurfaces::reflect(size_t, const float*, float*) const;
template void GlossySurfaces::reflect(size_t, const double*, double*) const;
template void GlossySurfaces::reflect(size_t, const openvdb::Vec3f*, openvdb::Vec3f*) const;
template void GlossySurfaces::reflect(size_t, const openvdb::Vec3d*, openvdb::Vec3d*) const;
template float GlossySurfaces::evaluate(const float*, const Vec3d&) const;
template double GlossySurfaces::evaluate(const double*, const Vec3d&) const;
template openvdb::Vec3f GlossySurfaces::evaluate(const openvdb::Vec3f*, const Vec3d&) const;
template openvdb::Vec3d GlossySurfaces::evaluate(const openvdb::Vec3d*, const Vec3d&) const;
template float GlossySurfaces::exitance(size_t, const float*) const;
template double GlossySurfaces::exitance(size_t, const double*) const;
template openvdb::Vec3f GlossySurfaces::exitance(size_t, const openvdb::Vec3f*) const;
template openvdb::Vec3d GlossySurfaces::exitance(size_t, const openvdb::Vec3d*) const;

} // namespace vdbrad
