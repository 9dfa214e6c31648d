#include "vdbrad/scene/Sky.h"

#include "vdbrad/core/Constants.h"

#include <openvdb/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <sstream>

namespace vdbrad {

using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {

// The up axis and the two horizontal ones, in Sun.h's order.
struct Frame
{
    int up, first, second;
    explicit Frame(int u)
        : up(u)
        , first(std::min((u + 1) % 3, (u + 2) % 3))
        , second(std::max((u + 1) % 3, (u + 2) % 3))
    {}
    // The unit world direction at polar angle theta (from up) and azimuth phi, radians.
    Vec3d direction(double theta, double phi) const
    {
        Vec3d d(0.0);
        d[up] = std::cos(theta);
        d[first] = std::sin(theta) * std::cos(phi);
        d[second] = std::sin(theta) * std::sin(phi);
        return d;
    }
};

double luminance(const Vec3d& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

uint64_t
fnv(const void* bytes, size_t size, uint64_t h)
{
    const unsigned char* p = static_cast<const unsigned char*>(bytes);
    for (size_t i = 0; i < size; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

void
checkFinite(double v, const char* what)
{
    if (!std::isfinite(v)) OPENVDB_THROW(openvdb::ValueError, what << " must be finite");
}

// Perez et al.'s sky luminance distribution, (1 + A e^(B / cos theta)) (1 + C e^(D gamma) +
// E cos^2 gamma), theta the view's polar angle, gamma its angle to the sun.
double
perez(const std::array<double, 5>& c, double theta, double gamma)
{
    const double cg = std::cos(gamma);
    return (1.0 + c[0] * std::exp(c[1] / std::cos(theta)))
        * (1.0 + c[2] * std::exp(c[3] * gamma) + c[4] * cg * cg);
}

// A latitude-longitude raster: rows of equal polar angle height from the pole of `up`.
double
rowSolidAngle(int row, int height, int width)
{
    const double t0 = kPi * row / height, t1 = kPi * (row + 1) / height;
    return (std::cos(t0) - std::cos(t1)) * 2.0 * kPi / width;
}

} // namespace

struct Sky::Data
{
    Kind kind = Kind::None;
    bool rgb = false;
    int up = 1;
    Vec3d uniform{0.0};
    // Clear: Preetham's Perez coefficients of Y, x and y and their zenith values over
    // F(0, theta_sun), the sun's direction and the ground's radiance.
    double zenith = 0.0, azimuth = 0.0, turbidity = 0.0, groundAlbedo = 0.0;
    Vec3d sunIrradiance{0.0};
    std::array<double, 5> perezY{}, perezX{}, perezYc{};
    double zenithY = 0.0, zenithX = 0.0, zenithYc = 0.0;
    Vec3d toSun{0.0, 1.0, 0.0};
    Vec3d ground{0.0};
    // Map: pixels top row first, rotation in radians.
    int width = 0, height = 0;
    std::vector<Vec3f> pixels;
    double rotation = 0.0;
    std::optional<Sun> sun;
    std::string splitNote;

    Vec3d radiance(const Vec3d& toward) const;
    Vec3d clearSky(const Vec3d& d) const;
    Vec3d mapAt(const Vec3d& d) const;
};

Vec3d
Sky::Data::clearSky(const Vec3d& d) const
{
    // As Blender's Preetham sky: the view's polar angle held just above the horizon, xyY to
    // XYZ to linear Rec. 709 (negative channels, out of gamut, clamped: radiance is >= 0).
    const double theta = std::min(std::acos(std::clamp(d[up], -1.0, 1.0)), 0.5 * kPi - 0.001);
    const double gamma = std::acos(std::clamp(d.dot(toSun), -1.0, 1.0));
    const double Y = zenithY * perez(perezY, theta, gamma);
    const double x = zenithX * perez(perezX, theta, gamma);
    const double y = zenithYc * perez(perezYc, theta, gamma);
    const double X = y != 0.0 ? x / y * Y : 0.0;
    const double Z = y != 0.0 ? (1.0 - x - y) / y * Y : 0.0;
    return Vec3d(std::max(0.0, 3.240479 * X - 1.537150 * Y - 0.498535 * Z),
        std::max(0.0, -0.969256 * X + 1.875991 * Y + 0.041556 * Z),
        std::max(0.0, 0.055648 * X - 0.204043 * Y + 1.057311 * Z));
}

Vec3d
Sky::Data::mapAt(const Vec3d& d) const
{
    // Bilinear between pixel centres, wrapping in azimuth.
    const Frame f(up);
    const double theta = std::acos(std::clamp(d[up], -1.0, 1.0));
    const double phi = std::atan2(d[f.second], d[f.first]) - rotation;
    double u = (0.5 - phi / (2.0 * kPi)) * width - 0.5;
    u -= std::floor(u / width) * width;
    const double v = std::clamp(theta / kPi * height - 0.5, 0.0, double(height - 1));
    const int u0 = std::min(int(u), width - 1), v0 = int(v);
    const int u1 = (u0 + 1) % width, v1 = std::min(v0 + 1, height - 1);
    const double a = u - u0, b = v - v0;
    auto px = [&](int col, int row) { return Vec3d(pixels[size_t(row) * width + col]); };
    return (px(u0, v0) * (1.0 - a) + px(u1, v0) * a) * (1.0 - b)
        + (px(u0, v1) * (1.0 - a) + px(u1, v1) * a) * b;
}

Vec3d
Sky::Data::radiance(const Vec3d& toward) const
{
    switch (kind) {
        case Kind::None: return Vec3d(0.0);
        case Kind::Uniform: return uniform;
        case Kind::Clear: {
            const Vec3d d = toward.unitSafe();
            return d[up] > 0.0 ? clearSky(d) : ground;
        }
        case Kind::Map: return mapAt(toward.unitSafe());
    }
    return Vec3d(0.0);
}

Sky
Sky::uniform(const Vec3d& radiance)
{
    for (int c = 0; c < 3; ++c) {
        if (!(radiance[c] >= 0.0) || !std::isfinite(radiance[c])) {
            OPENVDB_THROW(openvdb::ValueError, "the sky's radiance must be finite and >= 0, got "
                << radiance);
        }
    }
    auto data = std::make_shared<Data>();
    data->kind = Kind::Uniform;
    data->uniform = radiance;
    data->rgb = radiance[0] != radiance[1] || radiance[1] != radiance[2];
    Sky sky;
    sky.mData = std::move(data);
    return sky;
}

Sky
Sky::clear(double zenith, double azimuth, int up, double turbidity, double groundAlbedo,
    const Vec3d& sunIrradiance)
{
    checkFinite(azimuth, "the sun's azimuth");
    if (!(zenith >= 0.0 && zenith < 90.0)) {
        OPENVDB_THROW(openvdb::ValueError, "a clear sky needs the sun above the horizon: zenith "
            "in [0, 90) degrees, got " << zenith);
    }
    if (!(turbidity >= 1.0 && turbidity <= 10.0)) {
        OPENVDB_THROW(openvdb::ValueError, "the turbidity must be in [1, 10], got " << turbidity);
    }
    if (!(groundAlbedo >= 0.0 && groundAlbedo <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "the ground albedo must be in [0, 1], got "
            << groundAlbedo);
    }
    if (up < 0 || up > 2) OPENVDB_THROW(openvdb::ValueError, "the up axis must be 0, 1 or 2");
    for (int c = 0; c < 3; ++c) {
        if (!(sunIrradiance[c] >= 0.0) || !std::isfinite(sunIrradiance[c])) {
            OPENVDB_THROW(openvdb::ValueError, "the sun's irradiance must be finite and >= 0");
        }
    }
    auto data = std::make_shared<Data>();
    Data& d = *data;
    d.kind = Kind::Clear;
    d.rgb = true;
    d.up = up;
    d.zenith = zenith;
    d.azimuth = azimuth;
    d.turbidity = turbidity;
    d.groundAlbedo = groundAlbedo;
    d.sunIrradiance = sunIrradiance;
    const double ts = zenith * kPi / 180.0, T = turbidity;
    d.toSun = Frame(up).direction(ts, azimuth * kPi / 180.0);
    // Preetham et al. 1999, appendix A.2: the Perez coefficients' linear fits in T ...
    d.perezY = {0.1787 * T - 1.4630, -0.3554 * T + 0.4275, -0.0227 * T + 5.3251,
        0.1206 * T - 2.5771, -0.0670 * T + 0.3703};
    d.perezX = {-0.0193 * T - 0.2592, -0.0665 * T + 0.0008, -0.0004 * T + 0.2125,
        -0.0641 * T - 0.8989, -0.0033 * T + 0.0452};
    d.perezYc = {-0.0167 * T - 0.2608, -0.0950 * T + 0.0092, -0.0079 * T + 0.2102,
        -0.0441 * T - 1.6537, -0.0109 * T + 0.0529};
    // ... and the zenith's luminance (kcd/m^2) and chromaticity (theta_s in radians).
    const double chi = (4.0 / 9.0 - T / 120.0) * (kPi - 2.0 * ts);
    const double Yz = (4.0453 * T - 4.9710) * std::tan(chi) - 0.2155 * T + 2.4192;
    const double t1 = ts, t2 = ts * ts, t3 = t2 * ts;
    const double xz = T * T * (0.00166 * t3 - 0.00375 * t2 + 0.00209 * t1)
        + T * (-0.02903 * t3 + 0.06377 * t2 - 0.03202 * t1 + 0.00394)
        + (0.11693 * t3 - 0.21196 * t2 + 0.06052 * t1 + 0.25886);
    const double yz = T * T * (0.00275 * t3 - 0.00610 * t2 + 0.00317 * t1)
        + T * (-0.04214 * t3 + 0.08970 * t2 - 0.04153 * t1 + 0.00516)
        + (0.15346 * t3 - 0.26756 * t2 + 0.06670 * t1 + 0.26688);
    // Any value is its zenith value times F(theta, gamma) / F(0, theta_s).
    d.zenithY = Yz / perez(d.perezY, 0.0, ts);
    d.zenithX = xz / perez(d.perezX, 0.0, ts);
    d.zenithYc = yz / perez(d.perezYc, 0.0, ts);
    Sky sky;
    sky.mData = data;
    // The ground reflects what falls on it: the sky's horizontal irradiance and the sun's.
    d.ground = (sky.horizontalIrradiance() + sunIrradiance * std::cos(ts)) * (groundAlbedo / kPi);
    return sky;
}

Sky
Sky::fromMap(int width, int height, const std::vector<Vec3f>& pixels, int up, double rotation,
    const SunSplit& split)
{
    if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height)) {
        OPENVDB_THROW(openvdb::ValueError, "an environment map needs width x height pixels, got "
            << pixels.size() << " for " << width << " x " << height);
    }
    if (up < 0 || up > 2) OPENVDB_THROW(openvdb::ValueError, "the up axis must be 0, 1 or 2");
    checkFinite(rotation, "the map's rotation");
    auto data = std::make_shared<Data>();
    Data& d = *data;
    d.kind = Kind::Map;
    d.up = up;
    d.width = width;
    d.height = height;
    d.pixels = pixels;
    d.rotation = rotation * kPi / 180.0;
    std::vector<float> lum(pixels.size());
    // HDR files written by other tools hold small negative values (lossy compression, colour
    // space conversions): read as 0 and counted; NaN and infinity are refused.
    size_t negative = 0;
    float lowest = 0.f;
    for (size_t i = 0; i < pixels.size(); ++i) {
        Vec3f& p = d.pixels[i];
        bool clamped = false;
        for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(p[c])) {
                OPENVDB_THROW(openvdb::ValueError, "environment map pixel (" << i % size_t(width)
                    << ", " << i / size_t(width) << ") is " << p
                    << ": radiance must be finite");
            }
            if (p[c] < 0.f) {
                lowest = std::min(lowest, p[c]);
                p[c] = 0.f;
                clamped = true;
            }
        }
        negative += clamped;
        d.rgb = d.rgb || p[0] != p[1] || p[1] != p[2];
        lum[i] = float(luminance(Vec3d(p)));
    }
    const Frame f(up);
    auto pixelDirection = [&](size_t i) {
        const double col = double(i % size_t(width)) + 0.5, row = double(i / size_t(width)) + 0.5;
        return f.direction(kPi * row / height, 2.0 * kPi * (0.5 - col / width) + d.rotation);
    };
    auto solidAngle = [&](size_t i) { return rowSolidAngle(int(i / size_t(width)), height, width); };
    // f(j) for the 8 pixels around pixel i (wrapping in azimuth).
    auto neighbours = [&](size_t i, auto&& f) {
        const int col = int(i % size_t(width)), row = int(i / size_t(width));
        for (int dv = -1; dv <= 1; ++dv) {
            for (int du = -1; du <= 1; ++du) {
                const int r = row + dv;
                if ((du == 0 && dv == 0) || r < 0 || r >= height) continue;
                f(size_t(r) * size_t(width) + size_t((col + du + width) % width));
            }
        }
    };

    // The brightest compact region, split off as a sun.
    const size_t peak = size_t(std::max_element(lum.begin(), lum.end()) - lum.begin());
    std::vector<float> sorted = lum;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::ostringstream note;
    if (split.enabled && lum[peak] > 0.f && lum[peak] >= split.contrast * median) {
        const double threshold = std::max(split.contrast * median, lum[peak] / 1000.0);
        std::vector<char> in(pixels.size(), 0);
        std::vector<size_t> region{peak}, stack{peak};
        in[peak] = 1;
        double omega = 0.0;
        while (!stack.empty()) {
            const size_t i = stack.back();
            stack.pop_back();
            omega += solidAngle(i);
            neighbours(i, [&](size_t j) {
                if (in[j] || lum[j] < threshold) return;
                in[j] = 1;
                region.push_back(j);
                stack.push_back(j);
            });
        }
        const double diameter = 2.0 * std::acos(std::max(-1.0, 1.0 - omega / (2.0 * kPi)))
            * 180.0 / kPi;
        // What surrounds the region fills it: the mean of its outer ring, by solid angle.
        Vec3d fill(0.0);
        double ringOmega = 0.0;
        for (const size_t i : region) {
            neighbours(i, [&](size_t j) {
                if (in[j] != 0) return;
                in[j] = 2;   // counted once
                fill += Vec3d(d.pixels[j]) * solidAngle(j);
                ringOmega += solidAngle(j);
            });
        }
        if (ringOmega > 0.0) fill /= ringOmega;
        Vec3d power(0.0), centre(0.0);
        for (const size_t i : region) {
            const Vec3d excess = Vec3d(d.pixels[i]) - fill;
            const Vec3d part(std::max(0.0, excess[0]), std::max(0.0, excess[1]),
                std::max(0.0, excess[2]));
            power += part * solidAngle(i);
            centre += pixelDirection(i) * (luminance(part) * solidAngle(i));
        }
        const Vec3d toSun = centre.unitSafe();
        const double zenith = std::acos(std::clamp(toSun[up], -1.0, 1.0)) * 180.0 / kPi;
        // A coarse map's sun is a pixel or two wider than a real one: still a sun.
        if (diameter > split.maxDiameter && region.size() > 4) {
            note << "no sun split off: the brightest region is " << diameter << " degrees wide";
        } else if (!(zenith < 90.0)) {
            note << "no sun split off: the brightest region is below the horizon";
        } else {
            Sun sun;
            sun.zenith = zenith;
            sun.azimuth = std::atan2(toSun[f.second], toSun[f.first]) * 180.0 / kPi;
            sun.up = up;
            sun.irradiance = power;
            sun.diameter = std::min(diameter, 10.0);
            for (const size_t i : region) d.pixels[i] = Vec3f(fill);
            d.sun = sun;
            note << "a sun split off at zenith " << sun.zenith << ", azimuth " << sun.azimuth
                 << " degrees, " << sun.diameter << " degrees wide, irradiance " << power;
        }
    }
    if (negative > 0) {
        note << (note.tellp() > 0 ? "; " : "") << negative << " pixels with negative values "
             << "(down to " << lowest << ") read as 0";
    }
    d.splitNote = note.str();
    Sky sky;
    sky.mData = std::move(data);
    return sky;
}

Sky::Kind Sky::kind() const { return mData ? mData->kind : Kind::None; }
bool Sky::isRgb() const { return mData && mData->rgb; }

Vec3d
Sky::radiance(const Vec3d& toward) const
{
    return mData ? mData->radiance(toward) : Vec3d(0.0);
}

const std::optional<Sun>&
Sky::sun() const
{
    static const std::optional<Sun> none;
    return mData ? mData->sun : none;
}

Vec3d
Sky::horizontalIrradiance() const
{
    if (!mData) return Vec3d(0.0);
    // Midpoint rule on 256 rings x 512 azimuths over the upper hemisphere.
    const Frame f(mData->up);
    const int rings = 256, azimuths = 512;
    Vec3d sum(0.0);
    for (int r = 0; r < rings; ++r) {
        const double t0 = 0.5 * kPi * r / rings, t1 = 0.5 * kPi * (r + 1) / rings;
        const double theta = 0.5 * (t0 + t1);
        // The ring's cosine-weighted solid angle, exactly: pi (sin^2 t1 - sin^2 t0) / azimuths.
        const double w = kPi * (std::sin(t1) * std::sin(t1) - std::sin(t0) * std::sin(t0))
            / azimuths;
        for (int a = 0; a < azimuths; ++a) {
            sum += mData->radiance(f.direction(theta, 2.0 * kPi * (a + 0.5) / azimuths)) * w;
        }
    }
    return sum;
}

std::vector<Vec3f>
Sky::cellMeans(const DirectionSet& directions, const openvdb::math::Transform& transform) const
{
    const size_t cells = 2 * directions.size();
    std::vector<Vec3f> means(cells, Vec3f(0.f));
    if (!mData || directions.empty()) return means;
    if (mData->kind == Kind::Uniform) {
        std::fill(means.begin(), means.end(), Vec3f(mData->uniform));
        return means;
    }
    // The raster: a map's pixels, summed in b x b blocks when it has more than ~64 per cell;
    // an analytic sky sampled at ~32 per cell (at least 64 x 128).
    const Data& d = *mData;
    const Frame f(d.up);
    int W, H, block = 1;
    if (d.kind == Kind::Map) {
        const double per = double(d.width) * d.height / double(cells);
        block = std::max(1, int(std::floor(std::sqrt(per / 32.0))));
        W = (d.width + block - 1) / block;
        H = (d.height + block - 1) / block;
    } else {
        H = std::max(64, int(std::ceil(std::sqrt(32.0 * double(cells) / 2.0))));
        W = 2 * H;
    }
    std::vector<Vec3d> value(size_t(W) * H);
    std::vector<double> omega(size_t(W) * H);
    std::vector<uint32_t> cell(size_t(W) * H);
    const openvdb::math::MapBase& map = *transform.baseMap();
    tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& rows) {
        for (int r = rows.begin(); r != rows.end(); ++r) {
            for (int c = 0; c < W; ++c) {
                const size_t s = size_t(r) * W + c;
                double theta, phi;
                if (d.kind == Kind::Map) {
                    // The block's pixels: their radiance times solid angle, summed.
                    const int r0 = r * block, r1 = std::min(d.height, r0 + block);
                    const int c0 = c * block, c1 = std::min(d.width, c0 + block);
                    Vec3d sum(0.0);
                    double om = 0.0;
                    for (int pr = r0; pr < r1; ++pr) {
                        const double o = rowSolidAngle(pr, d.height, d.width);
                        for (int pc = c0; pc < c1; ++pc) {
                            sum += Vec3d(d.pixels[size_t(pr) * d.width + pc]) * o;
                            om += o;
                        }
                    }
                    value[s] = sum;
                    omega[s] = om;
                    theta = kPi * 0.5 * (r0 + r1) / d.height;
                    phi = 2.0 * kPi * (0.5 - 0.5 * (c0 + c1) / d.width) + d.rotation;
                } else {
                    theta = kPi * (r + 0.5) / H;
                    phi = 2.0 * kPi * (c + 0.5) / W;
                    omega[s] = rowSolidAngle(r, H, W);
                    value[s] = d.radiance(f.direction(theta, phi)) * omega[s];
                }
                cell[s] = uint32_t(directions.cellOf(
                    map.applyInverseJacobian(f.direction(theta, phi))));
            }
        }
    });
    // Summed in raster order: the same bits whatever the thread count.
    std::vector<Vec3d> sum(cells, Vec3d(0.0));
    std::vector<double> area(cells, 0.0);
    for (size_t s = 0; s < cell.size(); ++s) {
        sum[cell[s]] += value[s];
        area[cell[s]] += omega[s];
    }
    for (size_t k = 0; k < cells; ++k) {
        if (area[k] > 0.0) {
            means[k] = Vec3f(sum[k] / area[k]);
        } else {
            const Vec3d u = directions.unit(k / 2) * (k % 2 ? -1.0 : 1.0);
            means[k] = Vec3f(d.radiance(map.applyJacobian(u)));
        }
    }
    return means;
}

uint64_t
Sky::hash(uint64_t h) const
{
    if (!mData) return h;
    const Data& d = *mData;
    const int kind = int(d.kind);
    h = fnv(&kind, sizeof kind, h);
    h = fnv(&d.up, sizeof d.up, h);
    const double params[] = {d.uniform[0], d.uniform[1], d.uniform[2], d.zenith, d.azimuth,
        d.turbidity, d.groundAlbedo, d.sunIrradiance[0], d.sunIrradiance[1], d.sunIrradiance[2],
        d.rotation, double(d.width), double(d.height)};
    h = fnv(params, sizeof params, h);
    if (!d.pixels.empty()) h = fnv(d.pixels.data(), d.pixels.size() * sizeof(Vec3f), h);
    return h;
}

std::string
Sky::describe() const
{
    std::ostringstream os;
    if (!mData) return "no sky";
    const Data& d = *mData;
    switch (d.kind) {
        case Kind::None: os << "no sky"; break;
        case Kind::Uniform:
            os << "a uniform sky of radiance ";
            if (d.rgb) os << d.uniform; else os << d.uniform[0];
            break;
        case Kind::Clear:
            os << "a clear sky (Preetham, turbidity " << d.turbidity << ", sun at zenith "
               << d.zenith << ", azimuth " << d.azimuth << " degrees; ground albedo "
               << d.groundAlbedo << ")";
            break;
        case Kind::Map:
            os << "an environment map of " << d.width << " x " << d.height << " pixels";
            if (d.rotation != 0.0) os << " turned " << d.rotation * 180.0 / kPi << " degrees";
            if (!d.splitNote.empty()) os << "; " << d.splitNote;
            break;
    }
    return os.str();
}

} // namespace vdbrad
