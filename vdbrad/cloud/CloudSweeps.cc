#include "vdbrad/cloud/CloudTransferImpl.h"

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;

using Ray = detail::CloudRay;


// The source's rise across a step, from the steps before (dm) and after (dp): the monotonized
// central difference (second order where the source is smooth, no new extremum where it is not),
// kept within +-2 s so that the source stays >= 0 across the step.
inline float
sourceSlope(float s, const float* before, const float* after)
{
    float slope = 0.f;
    if (before && after) {
        const float dm = s - *before, dp = *after - s;
        if (dm * dp > 0.f) {
            const float c = 0.5f * (dm + dp);
            slope = std::copysign(std::min({std::abs(c), 2.f * std::abs(dm), 2.f * std::abs(dp)}),
                c);
        }
    } else if (before) {
        slope = s - *before;
    } else if (after) {
        slope = *after - s;
    }
    const float bound = 2.f * std::max(s, 0.f);
    return std::clamp(slope, -bound, bound);
}

// out[0, w) (+)= sum over h < H of a[h] b[h * stride + (0, w)]: one row of a small matrix
// product, in blocks of 16 accumulators that stay in registers (the compiler cannot keep a
// row it might alias with its inputs there; columns past the last whole block go one by one,
// which is why batches hold multiples of 8 directions, Impl::batchSize()). Compiled for AVX
// too, chosen at run time where the CPU has it: 8 lanes instead of SSE2's 4, and the same bits
// (separate multiplies and adds in the same order: no FMA, whose single rounding would change
// them).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target_clones("avx", "default")))
#endif
void
rowTimesMatrix(const float* a, const float* b, size_t H, size_t stride, size_t w, float* out,
    bool add)
{
    constexpr size_t kBlock = 16;
    size_t k0 = 0;
    for (; k0 + kBlock <= w; k0 += kBlock) {
        float acc[kBlock];
        for (size_t k = 0; k < kBlock; ++k) acc[k] = add ? out[k0 + k] : 0.f;
        for (size_t h = 0; h < H; ++h) {
            const float ah = a[h];
            const float* bh = b + h * stride + k0;
            for (size_t k = 0; k < kBlock; ++k) acc[k] += ah * bh[k];
        }
        for (size_t k = 0; k < kBlock; ++k) out[k0 + k] = acc[k];
    }
    for (size_t k = k0; k < w; ++k) {
        float acc = add ? out[k] : 0.f;
        for (size_t h = 0; h < H; ++h) acc += a[h] * b[h * stride + k];
        out[k] = acc;
    }
}

} // namespace

// Whether positions @a x and @a y of @a sweep's order are neighbours on a naive line of major
// axis @a major: one step apart along it, no gap between them.
template<typename SweepT>
inline bool
lineNeighbours(const SweepT& sweep, int major, uint32_t x, uint32_t y)
{
    return std::abs(sweep.coord(x)[major] - sweep.coord(y)[major]) == 1;
}

// t . n for the sense (forward: along @a unit) a line is swept in.
inline double
senseCosine(const Vec3d& unit, bool forward, const openvdb::Vec3f& n)
{
    return (forward ? 1.0 : -1.0) * unit.dot(Vec3d(n));
}

// A line in sense t meets surface voxel v, t.n_v = c != 0 (FogSurfaces.h), @a adjacent if v
// is the neighbour on the line of the voxel before it. A run of senders ends before a receiver
// and before a sender that is not its neighbour, sending @a sent(u) (the radiance leaving its
// last voxel u). A sender that does not continue a run takes what comes in from the medium
// voxel just before it (the fog is on its front side, whatever its normal says at a digital
// edge) and otherwise absorbs with its back what comes from behind (into @a backs, times
// @a etendue). Returns whether v takes the line's radiance (the caller lands it; the line then
// goes on dark): the first of a run of receivers, or a sender right after the medium.
template<typename SentT>
inline bool
meetSurface(Ray& ray, uint32_t v, double c, bool adjacent, double etendue, SentT&& sent,
    double& backs)
{
    const bool inRun = ray.run != FogSurfaces::kNone;
    const bool afterMedium = ray.medium && adjacent;
    ray.medium = false;
    if (c > 0.0 && inRun && adjacent) {
        ray.run = v;
        return false;
    }
    if (inRun) ray.radiance = sent(ray.run);
    ray.run = FogSurfaces::kNone;
    if (c > 0.0) {
        ray.run = v;
        ray.receiving = false;
        if (afterMedium) return true;
        backs += double(ray.radiance) * etendue;
        ray.radiance = 0.f;
        return false;
    }
    const bool first = inRun || !(ray.receiving && adjacent);
    ray.receiving = true;
    return first;
}

void
CloudTransfer::Impl::sweepBatch(const CloudTransfer& t, int g, const size_t* dirs, size_t count,
    Sweep& sw) const
{
    const size_t M = size_t(this->M), p = SweepSchedule::patternOf(g);
    Batch& batch = batches.local();
    const size_t W = batch.width = 2 * count, H = M - 1;
    if (M > 1) {
        // The harmonics l >= 1 of the batch's columns, both ways round: H x W for the sources,
        // W x H for the moments.
        batch.Yt.resize(2 * H * W);
        float* Yt = batch.Yt.data();
        float* Y = Yt + H * W;
        for (size_t k = 0; k < W; ++k) {
            const float* y = &phase.harmonics[(2 * dirs[k / 2] + k % 2) * M + 1];
            for (size_t h = 0; h < H; ++h) Yt[h * W + k] = Y[k * H + h] = y[h];
        }
        const std::vector<float>& S = sw.S[p];
        std::vector<float>& G = sw.G[size_t(g)];
        batch.R.resize(n * W);
        batch.Lbar.assign(n * W, 0.f);
        batch.G0.resize(n);
        batch.tile.resize(Batch::kTile * W);
        float* tile = batch.tile.data();
        for (size_t x0 = 0; x0 < n; x0 += Batch::kTile) {
            const size_t rows = std::min(Batch::kTile, n - x0);
            for (size_t i = 0; i < rows; ++i) {
                rowTimesMatrix(&S[(x0 + i) * M + 1], Yt, H, W, W, &tile[i * W], false);
                batch.G0[x0 + i] = G[(x0 + i) * M];
            }
            for (size_t k = 0; k < W; ++k) {
                for (size_t i = 0; i < rows; ++i) batch.R[k * n + x0 + i] = tile[i * W + k];
            }
        }
    }
    for (size_t j = 0; j < count; ++j) sweepDirection(t, g, dirs[j], 2 * j, batch, sw);
    if (M > 1) {
        // G[x, lm] += sum over columns of Lbar[x, k] Y_lm(k), l >= 1; I_00 back in its place.
        std::vector<float>& G = sw.G[size_t(g)];
        const float* Y = batch.Yt.data() + H * W;
        float* tile = batch.tile.data();
        for (size_t x0 = 0; x0 < n; x0 += Batch::kTile) {
            const size_t rows = std::min(Batch::kTile, n - x0);
            for (size_t k = 0; k < W; ++k) {
                for (size_t i = 0; i < rows; ++i) tile[i * W + k] = batch.Lbar[k * n + x0 + i];
            }
            for (size_t i = 0; i < rows; ++i) {
                rowTimesMatrix(&tile[i * W], Y, W, H, H, &G[(x0 + i) * M + 1], true);
                G[(x0 + i) * M] = batch.G0[x0 + i];
            }
        }
    }
}

// One direction of a group, both senses (sweepDirection()): what a line carries along it and
// what each voxel does to it, pass by pass. The first pass carries the sources; with periodic
// boundaries, the passes after it carry the light wrapping around the period.
struct CloudTransfer::Impl::DirectionPass
{
    const Impl& impl;
    const size_t d, M;
    Batch& batch;
    Sweep& sw;
    const SweepSchedule::Pattern& pattern;
    const std::vector<float>& S;
    const float* S0;   // per voxel, S's coefficient of Y_00 (Sweep::S0)
    const std::vector<float>& B;
    const float* E;
    const std::vector<float>& kappaP;
    std::array<double, 2>& escaped;
    double& skyEntered;
    const int up;
    // The line swept (the direction's own, or its projection across flat axes), its step in
    // voxels and its tube's etendue (cross-section 1 / step voxel faces times the solid angle
    // of one orientation).
    const SweptLine line;
    const Coord& sigma;
    const Vec3d& unit;
    const float step;
    const float omega;
    const double etendue;
    // Periodic: power entering each side face per layer (what left the opposite face), and
    // what leaves this pass.
    const PeriodicBoundary* periodic;
    std::vector<double> entry, exits;
    // The lines' keys, centred on the box: used only to find the side faces they cross.
    const LinePartition part;
    const float beamT[2];
    const float* yAcc[2];
    LineSweep::Lanes<Ray>& work;
    const int major;
    // Per sense, the batch's columns of R and Lbar (null where M = 1), and where I_00 gathers:
    // G[x M] where M = 1, the batch's G0 otherwise (Batch).
    const float* Rcol[2];
    float* LbarCol[2];
    float* G00;
    // The ground (Ground.h): where light lands, and per unit of reflected power the radiance
    // the upward sense gains (the downward sense and horizontal lines gain nothing).
    const GroundLayer* layer;
    std::vector<double>* landed;
    const bool upward[2];
    const double reflectedGain;
    // Surfaces (FogSurfaces.h): the rule at surface voxel v (passed over where the line runs
    // along it); a run of senders sends in the pass with the sources only.
    const std::vector<uint32_t>* surfaceP;
    std::vector<double>* onSurface;
    double& backs;
    bool sending = true;
    // The first pass's forward sense computes each voxel's exponential (every voxel is finished
    // once per sense and pass); the rest read it.
    std::vector<double>& absorbed;
    bool computing = true;

    DirectionPass(const Impl& i, const CloudTransfer& t, int g, size_t dir, size_t col,
        Batch& bt, Sweep& s)
        : impl(i), d(dir), M(size_t(i.M)), batch(bt), sw(s)
        , pattern(i.schedule->pattern(SweepSchedule::patternOf(g)))
        , S(s.S[SweepSchedule::patternOf(g)])
        , S0(M > 1 ? s.S0[SweepSchedule::patternOf(g)].data() : S.data())
        , B(s.B[SweepSchedule::patternOf(g)])
        , E(s.E[SweepSchedule::patternOf(g)].empty() ? nullptr
                                                      : s.E[SweepSchedule::patternOf(g)].data())
        , kappaP(i.kappaOrdered[SweepSchedule::patternOf(g)])
        , escaped(s.escaped[size_t(g)]), skyEntered(s.skyEntered[size_t(g)]), up(t.mOptions.up)
        , line(sweptLine(i.schedule->directions().direction(dir), i.flat))
        , sigma(line.sigma), unit(line.unit), step(line.step)
        , omega(float(kPi * i.schedule->directions().factor(dir)))
        , etendue(double(omega) / double(step))
        , periodic(i.boundary.get())
        , part(periodic ? periodic->partition(sigma) : LinePartition(sigma, LineType::Naive))
        , beamT{i.phase.beam[2 * dir], i.phase.beam[2 * dir + 1]}
        , yAcc{&i.phase.harmonics[2 * dir * M], &i.phase.harmonics[(2 * dir + 1) * M]}
        , work(i.lanes.local()), major(part.majorAxis())
        , Rcol{M > 1 ? bt.R.data() + col * i.n : nullptr,
               M > 1 ? bt.R.data() + (col + 1) * i.n : nullptr}
        , LbarCol{M > 1 ? bt.Lbar.data() + col * i.n : nullptr,
                  M > 1 ? bt.Lbar.data() + (col + 1) * i.n : nullptr}
        , G00(M > 1 ? bt.G0.data() : s.G[size_t(g)].data())
        , layer(i.ground ? &*i.ground : nullptr)
        , landed(layer ? &s.landed[size_t(g)] : nullptr)
        , upward{unit[up] > 0.0, unit[up] < 0.0}
        , reflectedGain(layer ? i.groundGain[dir] : 0.0)
        , surfaceP(i.surfaces ? &i.surfaceOrdered[SweepSchedule::patternOf(g)] : nullptr)
        , onSurface(i.surfaces ? &s.onSurface[size_t(g)] : nullptr)
        , backs(s.backs[size_t(g)]), absorbed(bt.absorbed)
    {
        if (periodic) {
            entry.assign(impl.leftFace.begin() + long(periodic->slice(d)),
                impl.leftFace.begin() + long(periodic->slice(d) + periodic->sliceSize()));
            exits.assign(periodic->sliceSize(), 0.0);
        }
        if (absorbed.size() < impl.n) absorbed.resize(impl.n);
    }

    // Light going down from voxel c along t onto the ground cell under it: wrapped around a
    // periodic box, missed (false) outside an open one's.
    bool land(const Coord& c, const Vec3d& t, double power)
    {
        const int64_t cell = layer->cellBelow(c.asVec3d(), t, periodic != nullptr);
        if (cell < 0) return false;
        (*landed)[size_t(cell)] += power;
        return true;
    }

    float sent(uint32_t u) const { return sending ? float(sw.surfaceEmits[u]) : 0.f; }

    // The line leaves surfaces: a run of senders sends; so does a receiver that the medium
    // voxel @a x (null: the line's end) follows right after (the mirror of a sender taking
    // what comes from the medium just before it).
    void endRun(Ray& ray, const uint32_t* x)
    {
        if (ray.run != FogSurfaces::kNone) {
            ray.radiance = sent(ray.run);
        } else if (ray.receiving && x && lineNeighbours(*pattern.sweep, major, *x, ray.last)) {
            ray.radiance = sent((*surfaceP)[ray.last]);
        }
        ray.run = FogSurfaces::kNone;
        ray.receiving = false;
    }

    void visitSurface(Ray& ray, uint32_t x, uint32_t v, bool forward)
    {
        const double c = senseCosine(unit, forward, impl.surfaces->normal(v));
        if (c == 0.0) return;
        const bool adjacent = lineNeighbours(*pattern.sweep, major, x, ray.last);
        if (meetSurface(ray, v, c, adjacent, etendue, [this](uint32_t u) { return sent(u); },
                backs)) {
            (*onSurface)[v] += double(ray.radiance) * etendue;
            ray.radiance = 0.f;
        }
        ray.last = x;
        ray.pending = false;
    }

    // The pending voxel of @a ray, its source rising by the slope from the one before it and
    // @a after (the next one's source, null at a gap or the line's end): its moments, and the
    // radiance that leaves it. Compiled apart for a constant source (Lin false), which is then
    // finished in place, at the constant scheme's cost.
    template<bool Lin>
    void finish(Ray& ray, float s, float r, float b, size_t sense, const float* after)
    {
        const uint32_t x = ray.last;
        const float tau = kappaP[x] * step;
        float absorb, mean, perTau = 0.f, slope = 0.f, gain = 0.f;
        if constexpr (Lin) {
            slope = sourceSlope(s, ray.hasBefore ? &ray.before : nullptr, after);
        }
        double a = 0.0;
        if (tau > kExponentialDepth) {
            if (computing) absorbed[x] = absorbedFraction(tau);
            a = absorbed[x];
        }
        if (slope != 0.f) gain = linearSourceGain(tau, a, perTau, absorb, mean);
        else stepFactors(tau, a, absorb, mean);
        const float* y = yAcc[sense];
        const float L = ray.radiance;
        // Mean over the step: s + (L - s) f - slope h / tau. I_00 gathers only
        // b + (L - b - r) f - slope h / tau; iterate() adds the rest, s0 (1 - f) + r, summed
        // over the directions in closed form (the self-scattering elimination), so that an
        // opaque voxel's I_00 is not a small difference of floats.
        const float rest = omega * (b + (L - b - r) * mean - slope * perTau);
        G00[x] += rest * y[0];
        if (M > 1) {
            // The higher moments: sweepBatch() multiplies this out.
            LbarCol[sense][x] += omega * (s + (L - s) * mean - slope * perTau);
        }
        ray.radiance = L + (s - L) * absorb + slope * gain;
        ray.pending = false;
    }

    // A ground cell: the voxel before it (going down) ends at a gap; light going up gathers
    // what the cell reflects (once per sweep: not in the wrap passes), light going down stays.
    template<bool Lin>
    void visitGround(uint32_t x, Ray& ray, size_t sense, bool sources)
    {
        if constexpr (Lin) {
            if (ray.pending) finish<Lin>(ray, ray.s, ray.r, ray.b, sense, nullptr);
            ray.hasBefore = false;
        }
        const size_t cell = layer->cell(pattern.sweep->coord(x));
        if (upward[sense]) {
            if (sources) ray.radiance += float(sw.groundEmits[cell] * reflectedGain);
        } else {
            (*landed)[cell] += double(ray.radiance) * etendue;
            ray.radiance = 0.f;
        }
        ray.last = x;
        ray.pending = false;
    }

    // Whether a line whose first voxel is x, travelling along sense @a forward, entered the box
    // from outside: not up out of the ground's layer (down into it, through the gaps of a
    // sparse medium, it did), nor out of a closed cavity a surface voxel faces (FogSurfaces.h).
    bool fromOutside(uint32_t x, bool forward) const
    {
        if (layer && layer->contains(pattern.sweep->coord(x))) {
            return (forward ? unit[up] : -unit[up]) < 0.0;
        }
        if (surfaceP) {
            const uint32_t v = (*surfaceP)[x];
            if (v != FogSurfaces::kNone && impl.enclosed[v]) return false;
        }
        return true;
    }

    // Voxel x of the pattern's order met by @a ray in sense @a forward.
    template<bool Lin>
    void visit(uint32_t x, Ray& ray, bool forward, bool sources)
    {
        if (!ray.started) {
            ray.started = true;
            int at = -1;
            if (periodic) {
                at = periodic->entering(part, sigma, pattern.sweep->coord(x),
                    forward ? unit : -unit, forward);
                if (at >= 0) {
                    const uint32_t c = periodic->enterCount(d, size_t(at));
                    ray.radiance = float(entry[size_t(at)] / c / etendue);
                }
            }
            // The sky, once per sweep (the pass with the sources), where the line comes in
            // from outside (an isolated line's tube has no cross-section).
            if (at < 0 && sources && !impl.skyIn.empty() && !line.isolated
                && fromOutside(x, forward)) {
                ray.radiance = impl.skyIn[2 * d + (forward ? 0 : 1)];
                skyEntered += double(ray.radiance) * etendue;
            }
        }
        // An isolated line holds one voxel: nothing comes in from the one before.
        if (line.isolated) ray.radiance = 0.f;
        const size_t sense = forward ? 0 : 1;
        if (layer && layer->contains(pattern.sweep->coord(x))) {
            visitGround<Lin>(x, ray, sense, sources);
            return;
        }
        if (surfaceP) {
            const uint32_t v = (*surfaceP)[x];
            if (v != FogSurfaces::kNone) {
                if constexpr (Lin) {
                    if (ray.pending) finish<Lin>(ray, ray.s, ray.r, ray.b, sense, nullptr);
                    ray.hasBefore = false;
                }
                visitSurface(ray, x, v, forward);
                return;
            }
            endRun(ray, &x);
            ray.medium = true;
        }
        const float* y = yAcc[sense];
        // The source: its isotropic part s0, its higher moments' part r and the beam's first
        // scattering b.
        float s0 = 0.f, r = 0.f, b = 0.f;
        if (sources) {
            s0 = S0[x] * y[0];
            if (M > 1) r = Rcol[sense][x];
            b = B[x] * beamT[sense];
            if (E) b += E[x];   // isotropic, fixed: gathered whole, as the beam's
        }
        const float s = s0 + r + b;
        if constexpr (Lin) {
            bool adjacent = false;
            if (ray.pending) {
                // Neighbours along the line: one step apart on its major axis (no gap).
                adjacent = lineNeighbours(*pattern.sweep, major, x, ray.last);
                finish<Lin>(ray, ray.s, ray.r, ray.b, sense, adjacent ? &s : nullptr);
                ray.before = ray.s;
            }
            ray.hasBefore = adjacent;
            ray.pending = true;
            ray.s = s;
            ray.r = r;
            ray.b = b;
        }
        ray.last = x;
        if constexpr (!Lin) finish<Lin>(ray, s, r, b, sense, nullptr);
    }

    // The lines' fronts at the end of a sense: their pending voxels finished, and the light
    // leaving the box (out of a side face of a periodic one, to the ground, or escaped).
    template<bool Lin>
    void leave(const Ray* fronts, size_t lines, bool forward)
    {
        const Vec3d dir = forward ? unit : -unit;
        for (size_t l = 0; l < lines; ++l) {
            Ray ray = fronts[l];
            if constexpr (Lin) {
                if (ray.pending) finish<Lin>(ray, ray.s, ray.r, ray.b, forward ? 0 : 1, nullptr);
            }
            if (surfaceP) {
                // A run that ends the line sends out of the box, unless it faces a closed
                // cavity (FogSurfaces.h).
                if (ray.run != FogSurfaces::kNone && impl.enclosed[ray.run]) {
                    ray.run = FogSurfaces::kNone;
                }
                endRun(ray, nullptr);
            }
            // (An isolated line's tube has no cross-section: nothing leaves it.)
            if (!ray.started || ray.radiance == 0.f || line.isolated) continue;
            const double power = double(ray.radiance) * etendue;
            if (periodic) {
                const int at = periodic->leaving(part, sigma, pattern.sweep->coord(ray.last), dir,
                    forward);
                if (at >= 0) { exits[size_t(at)] += power; continue; }
            }
            if (dir[up] == 0.0) {
                escaped[0] += 0.5 * power;
                escaped[1] += 0.5 * power;
            } else if (dir[up] < 0.0 && layer
                && land(pattern.sweep->coord(ray.last), dir, power)) {
                // A line that ends above the ground without crossing its layer (at the bound
                // of a centred partition's central line): on the cell where it meets the layer.
            } else {
                escaped[dir[up] > 0.0 ? 1 : 0] += power;
            }
        }
        if (forward) computing = false;
    }

    // One pass; a pass without sources (light wrapping a periodic box) has nothing to slope.
    template<bool Lin>
    void pass(bool sources)
    {
        sending = sources;
        std::fill(exits.begin(), exits.end(), 0.0);
        pattern.sweep->walk(sigma, impl.schedule->reversed(d), work,
            [&](uint32_t x, Ray& ray, bool forward) { visit<Lin>(x, ray, forward, sources); },
            [&](const Ray* fronts, size_t lines, bool forward) {
                leave<Lin>(fronts, lines, forward);
            });
    }
};

// Direction d of group g, both senses, columns @a column and @a column + 1 of @a batch: the
// pass with the sources, then (periodic) the passes of the light wrapping around the period.
void
CloudTransfer::Impl::sweepDirection(const CloudTransfer& t, int g, size_t d, size_t column,
    Batch& batch, Sweep& sw) const
{
    DirectionPass p(*this, t, g, d, column, batch, sw);
    const PeriodicBoundary* periodic = boundary.get();
    if (periodic && !skyIn.empty() && !p.line.isolated) {
        // Horizontal directions never enter through the top or bottom: their half cells drift
        // in from outside the box through the side faces.
        const double rise = periodic->rise(schedule->directions(), d);
        p.skyEntered += periodic->skyDrift(d, rise, {skyIn[2 * d], skyIn[2 * d + 1]}, p.etendue,
            p.entry);
    }
    if (t.mOptions.source == VoxelSource::Linear) p.pass<true>(true);
    else p.pass<false>(true);
    if (periodic && !p.line.isolated) {
        periodic->followWraps(d, periodic->rise(schedule->directions(), d), p.unit[t.mOptions.up],
            p.entry, p.exits, [&] { p.pass<false>(false); }, &sw.leftNow[periodic->slice(d)],
            sw.escaped[size_t(g)]);
    }
}

std::vector<double>
CloudTransfer::Impl::surfaceAreas() const
{
    // Per group, then added in a fixed order: the same bits for any thread count.
    const size_t count = surfaces->size();
    std::array<std::vector<double>, kGroups> parts;
    const SweepProgress progress(nullptr, schedule->directions().size());
    schedule->forEachGroup(progress, "surface areas", [](int) { return true; }, [&](int g) {
        const size_t p = SweepSchedule::patternOf(g);
        const SweepSchedule::Pattern& pattern = schedule->pattern(p);
        const std::vector<uint32_t>& surfaceP = surfaceOrdered[p];
        std::vector<double>& area = parts[size_t(g)];
        area.assign(count, 0.0);
        LineSweep::Lanes<Ray>& work = lanes.local();
        double backs = 0.0;
        auto none = [](uint32_t) { return 0.f; };
        schedule->forDirections(g, [&](size_t d) {
            const SweptLine line = sweptLine(schedule->directions().direction(d), flat);
            const double etendue = double(float(kPi * schedule->directions().factor(d)))
                / double(line.step);
            const int major = LinePartition(line.sigma, LineType::Naive).majorAxis();
            pattern.sweep->walk(line.sigma, schedule->reversed(d), work,
                [&](uint32_t x, Ray& ray, bool forward) {
                    const uint32_t v = surfaceP[x];
                    if (v == FogSurfaces::kNone) {
                        ray.run = FogSurfaces::kNone;
                        ray.receiving = false;
                        ray.medium = true;
                    } else {
                        const double c = senseCosine(line.unit, forward, surfaces->normal(v));
                        if (c == 0.0) return;
                        const bool adjacent = ray.started
                            && lineNeighbours(*pattern.sweep, major, x, ray.last);
                        // A line's first voxel receives from outside the box: not where it
                        // faces a closed cavity (the mirror of the sweep's rule at line ends).
                        if (meetSurface(ray, v, c, adjacent, etendue, none, backs)
                            && (ray.started || !enclosed[v])) {
                            area[v] += etendue;
                        }
                    }
                    ray.started = true;
                    ray.last = x;
                },
                [](const Ray*, size_t, bool) {});
        });
    });
    std::vector<double> A(count, 0.0);
    for (const std::vector<double>& part : parts) {
        for (size_t v = 0; v < part.size(); ++v) A[v] += part[v];
    }
    for (size_t v = 0; v < count; ++v) A[v] = surfaceNorm[v] > 0.0 ? A[v] / surfaceNorm[v] : 0.0;
    return A;
}

double
CloudTransfer::iterate(openvdb::util::NullInterrupter* interrupt)
{
    return mIteration.iterate([&] { return sweep(interrupt); });
}

double
CloudTransfer::sweep(openvdb::util::NullInterrupter* interrupt)
{
    Impl& impl = *mImpl;
    const SweepSchedule& schedule = *impl.schedule;
    const size_t n = impl.n;
    const size_t M = size_t(impl.M);
    const Impl::Sources source = impl.sources();
    // The sources in each pattern's order, so that the sweeps read them sequentially.
    std::array<std::vector<float>, SweepSchedule::kPatterns> S, S0, B, E;
    for (size_t p = 0; p < S.size(); ++p) {
        if (schedule.pattern(p).empty()) continue;
        schedule.toPatternOrder(p, source.source, S[p], M);
        if (M > 1) {
            S0[p].resize(n);
            const float* from = S[p].data();
            float* to = S0[p].data();
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t x = r.begin(); x != r.end(); ++x) to[x] = from[x * M];
                });
        }
        schedule.toPatternOrder(p, source.beam, B[p]);
        if (!impl.emitSource.empty()) schedule.toPatternOrder(p, impl.emitSource, E[p]);
    }
    // What each ground cell reflects in this sweep: its albedo times what reached it.
    const size_t cells = impl.groundDiffuse.size();
    std::vector<double> emits(cells);
    for (size_t c = 0; c < cells; ++c) {
        emits[c] = impl.groundAlbedo * (impl.groundDirect[c] + impl.groundDiffuse[c]);
    }
    // What each surface voxel sends in this sweep, over Z_v: its emission and its albedo times
    // what reached its front.
    const size_t surfaceCount = impl.surfaceLanded.size();
    std::vector<double> surfaceEmits(surfaceCount);
    for (size_t v = 0; v < surfaceCount; ++v) surfaceEmits[v] = impl.surfaceSends(v);
    Impl::Sweep sw{S, S0, B, E, emits, {}, {}, std::vector<double>(impl.leftFace.size(), 0.0), {},
        surfaceEmits, {}, {}};
    // Under MPI each rank sweeps its own groups (Distribution.h).
    const Distribution& ranks = Distribution::orAlone(mOptions.ranks, impl.alone);
    SweepProgress progress(interrupt, schedule.directionsOf([&](int g) { return ranks.owns(g); }));
    const size_t perBatch = Impl::batchSize(n, M);
    schedule.round(progress, "cloud transfer", ranks, [](int) { return true; },
        [&](int g) {
            sw.G[size_t(g)].assign(n * M, 0.f);
            sw.landed[size_t(g)].assign(cells, 0.0);
            sw.onSurface[size_t(g)].assign(surfaceCount, 0.0);
            std::vector<size_t> dirs;
            schedule.forDirections(g, [&](size_t d) { dirs.push_back(d); });
            for (size_t b = 0; b < dirs.size() && !progress.cancelled(); b += perBatch) {
                const size_t count = std::min(perBatch, dirs.size() - b);
                impl.sweepBatch(*this, g, &dirs[b], count, sw);
                progress.finished(count);
            }
        },
        [&](int g, int owner) {
            ranks.share(sw.G[size_t(g)], n * M, owner);
            ranks.share(sw.landed[size_t(g)], cells, owner);
            ranks.share(sw.onSurface[size_t(g)], surfaceCount, owner);
            ranks.share(sw.escaped[size_t(g)].data(), sizeof(double) * 2, owner);
            ranks.share(&sw.backs[size_t(g)], sizeof(double), owner);
            ranks.share(&sw.skyEntered[size_t(g)], sizeof(double), owner);
        });
    // The light wrapping a periodic box: one slice per direction, written by its owner alone.
    ranks.combine(sw.leftNow);
    // Moments from the groups, in a fixed order (bit-identical for any thread count).
    std::vector<double> sum(n * M, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) schedule.sum(sw.G, i, M, &sum[i * M]);
    });
    // The state this sweep started from, for the Anderson step below.
    const std::vector<float> x = impl.mixer ? impl.mixedState() : std::vector<float>();
    // Light that reached the ground, the groups added in a fixed order.
    std::vector<double> landed(cells, 0.0);
    for (const std::vector<double>& part : sw.landed) {
        for (size_t c = 0; c < cells; ++c) landed[c] += part[c];
    }
    // I_00 before the elimination overwrites it: the diffusion's residual is formed from it.
    std::vector<float> before;
    impl.eliminateSelfScattering(sum, source.isoExcess, impl.diffusion ? &before : nullptr);
    if (impl.diffusion) impl.accelerateDiffusion(sum, before);
    Impl::Change change;
    const double absorbed = impl.updateMeanRadiance(sum, change);
    const auto [onGround, directOnGround] = impl.updateGround(landed, change);
    const double surfaceAbsorbed = impl.updateSurfaces(sw, change);
    if (impl.boundary) impl.leftFace.swap(sw.leftNow);
    if (impl.mixer) impl.mix(x);
    // Light leaving the box, added in a fixed order: pattern by pattern, then its two halves
    // (the order these double sums had before the groups were numbered as SweepSchedule
    // numbers them, so that the budget kept its bits).
    double up0 = 0.0, down0 = 0.0;
    for (int p = 0; p < SweepSchedule::kPatterns; ++p) {
        for (int half = 0; half < SweepSchedule::kGroups / SweepSchedule::kPatterns; ++half) {
            const size_t g = size_t(half * SweepSchedule::kPatterns + p);
            const std::array<double, 2>& e = sw.escaped[g];
            down0 += e[0];
            up0 += e[1];
        }
    }
    // The sky's power, the groups added in a fixed order.
    impl.skyIncident = 0.0;
    for (double e : sw.skyEntered) impl.skyIncident += e;
    const double total = impl.incident + impl.skyIncident + impl.emitted + impl.mediumEmitted;
    const double in = total > 0.0 ? total : 1.0;
    mBudget.incident = total * impl.outputScale;
    mBudget.sky = impl.skyIncident / in;
    mBudget.emitted = (impl.emitted + impl.mediumEmitted) / in;
    mBudget.mediumEmitted = impl.mediumEmitted / in;
    mBudget.surfaceAbsorptance = surfaceAbsorbed / in;
    mBudget.albedo = up0 / in;
    mBudget.transmittance = (down0 + impl.directOut + onGround) / in;
    mBudget.directTransmittance = (impl.directOut + directOnGround) / in;
    mBudget.absorptance = absorbed / in;
    mBudget.groundReflected = impl.groundAlbedo * onGround / in;
    return change.size > 0.0 ? change.max / change.size : 0.0;
}

} // namespace vdbrad
