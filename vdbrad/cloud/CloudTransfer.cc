#include "vdbrad/cloud/CloudTransferImpl.h"

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;

// The options' ranges (the first error, in one line), before anything is built.
void
checkOptions(const CloudTransferOptions& options)
{
    if (!(options.sunZenith >= 0.0 && options.sunZenith <= 89.9)) {
        OPENVDB_THROW(openvdb::ValueError, "sun zenith angle must be in [0, 89.9] degrees, got "
            << options.sunZenith);
    }
    if (!std::isfinite(options.sunAzimuth)) {
        OPENVDB_THROW(openvdb::ValueError, "sun azimuth must be finite");
    }
    if (options.up < 0 || options.up > 2) {
        OPENVDB_THROW(openvdb::ValueError, "up must be 0, 1 or 2");
    }
    if (options.minPeriod < -1) {
        OPENVDB_THROW(openvdb::ValueError, "minimum period must be >= 0 voxels (or -1: auto), got "
            << options.minPeriod);
    }
    if (options.channel < 0 || options.channel > 2) {
        OPENVDB_THROW(openvdb::ValueError, "channel must be 0, 1 or 2, got " << options.channel);
    }
    if (options.phaseOrder < -1) {
        OPENVDB_THROW(openvdb::ValueError, "phase order must be >= 0 (or -1: auto), got "
            << options.phaseOrder);
    }
    for (int c = 0; c < 3; ++c) {
        if (!(options.sunColour[c] >= 0.0 && std::isfinite(options.sunColour[c]))) {
            OPENVDB_THROW(openvdb::ValueError, "sun colour must be finite and >= 0, got "
                << options.sunColour);
        }
    }
    if (options.groundAlbedo && !(*options.groundAlbedo >= 0.0 && *options.groundAlbedo <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "ground albedo must be in [0, 1], got "
            << *options.groundAlbedo);
    }
}

} // namespace

CloudTransfer::CloudTransfer(const Cloud& given, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt)
    : IterativeSolver(FixedPointIteration(options.maxIterations, options.tolerance,
          chooseAcceleration(given, options), options.andersonDepth))
    , mCloud(given), mOptions(options)
    , mImpl(new Impl)
{
    const auto start = std::chrono::steady_clock::now();
    checkOptions(options);
    mOptions.phaseOrder = phaseOrderFor(options);
    mOptions.directions = directionCount(options);
    mOptions.accelerate = mIteration.acceleration();   // chosen once, for the base class
    DirectionSet directions = DirectionSet::fromCount(mOptions.directions);
    // Anisotropic scattering projects the radiance on harmonics up to order K and evaluates
    // the source from them: weights exact for products of two of them (degree 2K) keep that
    // projection from aliasing (HarmonicQuadrature.h).
    const int order = phaseOrderFor(options);
    if (order > 0 && options.harmonicWeights) {
        HarmonicQuadrature fit = fitHarmonicQuadrature(directions,
            std::min(2 * order, kMaxQuadratureDegree));
        mQuadratureDegree = fit.degree;
        directions = directions.withFactors(std::move(fit.factors));
    }
    Impl& impl = *mImpl;
    mCopies = copiesFor(given, options, directions.size());
    impl.assemble(given, options, mCopies);
    // From here on, the medium solved.
    const Cloud& cloud = impl.solved ? *impl.solved : given;
    impl.setMedium(cloud, options, order);
    const Vec3d toSun = sunDirection(options.sunZenith, options.sunAzimuth, options.up,
        cloud.transform());
    impl.toSun = toSun.unit();
    impl.traceBeam(cloud, options, toSun, interrupt);
    impl.setSky(options, directions, cloud.transform());
    if (!given.emission().isZero()) impl.setEmission(given, options, cloud.voxelSize());
    impl.diffuseJ.assign(impl.n, 0.f);
    impl.moments.assign(impl.n * size_t(impl.M), 0.f);
    impl.phase = options.phase.tables(directions, order, (-toSun).unit());
    impl.layOut(cloud, options, std::move(directions));
    // The moments, the light carried across periodic side faces and the ground's (see
    // iterate()).
    impl.mixer = mIteration.makeMixer<float>(impl.n * impl.mixedMoments() + impl.leftFace.size()
        + impl.groundDiffuse.size() + impl.surfaceLanded.size());
    impl.setEscapeFactors(options.up);
    impl.setDiffusion(cloud, options);
    mIteration.addSeconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

// The medium solved, where it is not the cloud as given: a periodic box filled (filledBox()),
// copies side by side (@a copies), a ground's layer under them, surface voxels merged in;
// copyOf maps each voxel to the given cloud's (kNoCloudVoxel: none).
void
CloudTransfer::Impl::assemble(const Cloud& given, const CloudTransferOptions& options,
    const Coord& copies)
{
    if (options.periodic && given.size() < given.voxels().bbox().volume()) {
        solved.reset(new Cloud(filledBox(given, &copyOf)));
    }
    if (copies != Coord(1)) {
        std::vector<uint32_t> from;
        Cloud tiled = tileCloud(solved ? *solved : given, copies, &from);
        if (solved) {
            for (uint32_t& f : from) f = copyOf[f];
        }
        copyOf = std::move(from);
        solved.reset(new Cloud(std::move(tiled)));
    }
    if (options.groundAlbedo) {
        groundAlbedo = *options.groundAlbedo;
        const Cloud& above = solved ? *solved : given;
        ground.emplace(above.voxels().bbox(), options.up);
        std::vector<uint32_t> from;
        Cloud grounded = ground->withGround(above, &from);
        if (solved) {
            for (uint32_t& f : from) if (f != GroundLayer::kGround) f = copyOf[f];
        }
        copyOf = std::move(from);
        solved.reset(new Cloud(std::move(grounded)));
    }
    if (options.surfaces) {
        if (options.periodic || options.groundAlbedo) {
            OPENVDB_THROW(openvdb::ValueError, "surfaces inside a cloud are solved in an open "
                "box without a ground (give the ground as surface voxels)");
        }
        surfaces.reset(new FogSurfaces(*options.surfaces, options.channel));
        std::vector<uint32_t> from;
        Cloud merged = surfaces->merged(given, from, surfaceOf);
        static_assert(FogSurfaces::kNone == GroundLayer::kGround && kNoCloudVoxel
            == GroundLayer::kGround, "one mark for no cloud voxel");
        copyOf = std::move(from);
        solved.reset(new Cloud(std::move(merged)));
    }
}

// Per voxel of the medium solved: optical depth kappa and albedo omega0, delta-M scaled for
// the phase function's order.
void
CloudTransfer::Impl::setMedium(const Cloud& cloud, const CloudTransferOptions& options, int order)
{
    n = cloud.size();
    const double h = cloud.voxelSize();
    kappa.resize(n);
    omega.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const double k = double(cloud.extinction(i)) * h;
        if (!std::isfinite(k)) {
            OPENVDB_THROW(openvdb::ValueError, "voxel optical depth overflows (extinction "
                << cloud.extinction(i) << " per unit, voxel size " << h << ")");
        }
        kappa[i] = float(k);
        omega[i] = channelOf(cloud.albedo(), i, options.channel);
    }
    // Phase function: order K and delta-M scaling of extinction and albedo.
    const PhaseFunction::Truncated trunc = options.phase.truncate(order);
    chi = trunc.chi;
    M = (order + 1) * (order + 1);
    if (trunc.f > 0.0) {
        for (size_t i = 0; i < n; ++i) {
            const double w = omega[i], scaled = 1.0 - w * trunc.f;
            kappa[i] = float(kappa[i] * scaled);
            omega[i] = scaled > 0.0 ? float(w * (1.0 - trunc.f) / scaled) : 0.f;
        }
    }
}

// The sun's direct beam through the medium (SolarBeam.h): what each voxel takes from it, what
// reaches the ground and the surfaces, and the beam's mean radiance.
void
CloudTransfer::Impl::traceBeam(const Cloud& cloud, const CloudTransferOptions& options,
    const Vec3d& toSun, openvdb::util::NullInterrupter* interrupt)
{
    const int up = options.up;
    if (interrupt) interrupt->start("solar beam");
    // The transfer runs at the irradiance divided by a power of two that brings it to [0.5, 1),
    // and intensities are multiplied back on output (both exact): flush-to-zero (Denormals.h)
    // then cuts at the same relative level for any F0, and F0 = 2^k F gives 2^k times the bits.
    // Without a sun, the sky's horizontal irradiance sets the scale.
    const double F0 = options.irradiance * options.sunColour[options.channel];
    const double reference = F0 > 0.0 || options.sky.empty() ? F0
        : options.sky.horizontalIrradiance()[options.channel];
    int exponent = 0;
    if (reference > 0.0 && std::isfinite(reference)) std::frexp(reference, &exponent);
    outputScale = std::ldexp(1.0, exponent);
    const GroundLayer* layer = ground ? &*ground : nullptr;
    std::vector<uint8_t> opaque;
    if (surfaces) {
        opaque.resize(n);
        for (size_t i = 0; i < n; ++i) opaque[i] = surfaceOf[i] != FogSurfaces::kNone;
    }
    SolarBeamResult beam = traceSolarBeam(cloud.voxels(), kappa, toSun, up, options.periodic,
        options.beamRaysPerVoxel, F0 / outputScale, interrupt, layer,
        surfaces ? &opaque : nullptr);
    if (interrupt) interrupt->end();
    incident = beam.incident;
    deposited = std::move(beam.deposited);
    // What lands on the ground is counted there (sweep()); directOut is the rest.
    directOut = beam.transmitted;
    if (ground) {
        groundDirect = std::move(beam.ground);
        groundDiffuse.assign(ground->size(), 0.0);
        for (double e : groundDirect) directOut -= e;
        directOut = std::max(directOut, 0.0);
    }
    if (surfaces) {
        // The beam's power on a surface voxel: on its front if the beam meets it from there.
        surfaceDirect.assign(surfaces->size(), 0.0);
        surfaceLanded.assign(surfaces->size(), 0.0);
        for (size_t i = 0; i < n; ++i) {
            const uint32_t s = surfaceOf[i];
            if (s == FogSurfaces::kNone) continue;
            if (toSun.dot(Vec3d(surfaces->normal(s))) > 0.0) {
                surfaceDirect[s] += deposited[i];
            } else {
                backDirect += deposited[i];
            }
            deposited[i] = 0.0;
        }
    }
    beamJ.resize(n);
    for (size_t i = 0; i < n; ++i) {
        beamJ[i] = kappa[i] > 0.f
            ? float(deposited[i] / (4.0 * kPi * double(kappa[i]))) : 0.f;
    }
}

// The sky: per direction and sense, its mean radiance over the cell a line comes from.
void
CloudTransfer::Impl::setSky(const CloudTransferOptions& options, const DirectionSet& directions,
    const openvdb::math::Transform& transform)
{
    skyIn.clear();
    if (options.sky.empty()) return;
    const std::vector<openvdb::Vec3f> cells = options.sky.cellMeans(directions, transform);
    skyIn.resize(cells.size());
    for (size_t d = 0; d < cells.size() / 2; ++d) {
        // Light travelling along +sigma comes from the sky seen along -sigma.
        skyIn[2 * d] = float(cells[2 * d + 1][options.channel] / outputScale);
        skyIn[2 * d + 1] = float(cells[2 * d][options.channel] / outputScale);
    }
    if (std::all_of(skyIn.begin(), skyIn.end(), [](float L) { return L == 0.f; })) skyIn.clear();
}

// The medium's own emission (fire): a fixed source.
void
CloudTransfer::Impl::setEmission(const Cloud& given, const CloudTransferOptions& options,
    double h)
{
    // epsilon / sigma_t with sigma_t as the sweeps see it (delta-M scaled); copies, the
    // ground's layer and surface voxels take their source voxel's (none for the last two).
    emitSource.assign(n, 0.f);
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const uint32_t from = copyOf.empty() ? uint32_t(i) : copyOf[i];
        if (from == GroundLayer::kGround || !(kappa[i] > 0.f)) continue;
        const double e = channelOf(given.emission(), from, options.channel) * h
            / outputScale;
        emitSource[i] = float(e / double(kappa[i]));
        total += 4.0 * kPi * e;   // 4 pi epsilon V, in the beam's units (voxel faces)
    }
    mediumEmitted = total;
}

// Sweep orders (naive lines: their steps have exact lengths), the per-voxel arrays in them, and
// periodic boundaries.
void
CloudTransfer::Impl::layOut(const Cloud& cloud, const CloudTransferOptions& options,
    DirectionSet directions)
{
    const int up = options.up;
    schedule.reset(new SweepSchedule(cloud.voxels(), std::move(directions),
        SweepSchedule::Layout()));
    for (size_t p = 0; p < kappaOrdered.size(); ++p) {
        if (!schedule->pattern(p).empty()) {
            schedule->toPatternOrder(p, kappa, kappaOrdered[p]);
        }
    }
    if (surfaces) {
        for (size_t p = 0; p < surfaceOrdered.size(); ++p) {
            if (!schedule->pattern(p).empty()) {
                schedule->toPatternOrder(p, surfaceOf, surfaceOrdered[p]);
            }
        }
    }
    if (options.periodic) {
        flat = PeriodicBoundary::flatAxes(cloud.voxels().bbox().dim(), up);
        boundary.reset(new PeriodicBoundary(cloud.voxels().bbox(), up, *schedule, flat));
        leftFace.assign(boundary->size(), 0.0);
    }
}

// Escape factors for the self-scattering elimination (iterate()): per direction, the weight
// Omega (Y_00^2 of both senses) the sweeps use; a ground's and the surfaces' gains likewise.
void
CloudTransfer::Impl::setEscapeFactors(int up)
{
    const size_t dirs = schedule->directions().size();
    std::vector<double> weight(dirs);
    std::vector<float> step(dirs);
    const size_t M = size_t(this->M);
    const std::vector<float>& y = phase.harmonics;
    for (size_t d = 0; d < dirs; ++d) {
        const double y0 = y[2 * d * M], y1 = y[(2 * d + 1) * M];
        weight[d] = double(float(kPi * schedule->directions().factor(d))) * (y0 * y0 + y1 * y1);
        step[d] = sweptLine(schedule->directions().direction(d), flat).step;
    }
    escape = meanEscapeFactors(kappa, step, weight);
    if (ground) {
        std::vector<float> solidAngle(dirs);
        std::vector<double> mu(dirs);
        for (size_t d = 0; d < dirs; ++d) {
            solidAngle[d] = float(kPi * schedule->directions().factor(d));
            mu[d] = std::abs(schedule->directions().unit(d)[up]);
        }
        groundGain = groundEmission(solidAngle, mu, step);
    }
    if (surfaces) {
        std::vector<Vec3d> units(dirs);
        std::vector<float> solidAngle(dirs);
        for (size_t d = 0; d < dirs; ++d) {
            units[d] = sweptLine(schedule->directions().direction(d), flat).unit;
            solidAngle[d] = float(kPi * schedule->directions().factor(d));
        }
        surfaceNorm = surfaces->normalisers(units, solidAngle);
        const Regions regions = findRegions(surfaces->scene().voxels(),
            surfaces->scene().normals(), LineType::Naive);
        enclosed.resize(surfaces->size());
        for (size_t v = 0; v < enclosed.size(); ++v) {
            enclosed[v] = regions.region[v] != 0;
        }
        surfaceArea = surfaceAreas();
        for (size_t v = 0; v < surfaceArea.size(); ++v) {
            emitted += double(surfaces->emission(v)) * surfaceArea[v];
        }
        emitted /= outputScale;
    }
}

// Diffusion synthetic acceleration (DiffusionAcceleration.h) over the medium's voxels: the
// ground's layer and surface voxels are walls of their albedo.
void
CloudTransfer::Impl::setDiffusion(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (!options.diffusion || options.phase.asymmetry() < DiffusionAcceleration::kMinAsymmetry) {
        return;
    }
    std::vector<float> wall(n, DiffusionAcceleration::kMedium);
    for (size_t i = 0; i < n; ++i) {
        if (surfaces && surfaceOf[i] != FogSurfaces::kNone) {
            wall[i] = surfaces->albedo(surfaceOf[i]);
        } else if (ground && copyOf[i] == GroundLayer::kGround) {
            wall[i] = float(groundAlbedo);
        }
    }
    std::optional<openvdb::CoordBBox> period;
    if (options.periodic) {
        period = cloud.voxels().bbox();
        if (ground) period->min()[options.up] += 1;   // the ground's layer is under the box
    }
    diffusion.reset(new DiffusionAcceleration(cloud.voxels(), kappa, omega, escape,
        chi.size() > 1 ? chi[1] : 0.0, wall, period, options.up));
}

CloudTransfer::~CloudTransfer() = default;

const DirectionSet&
CloudTransfer::directions() const
{
    return mImpl->schedule->directions();
}

Coord
CloudTransfer::periodicCopies(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (!options.periodic || options.minPeriod == 0) return Coord(1);
    return copiesFor(cloud, options, DirectionSet::fromCount(directionCount(options)).size());
}

int
CloudTransfer::phaseOrderFor(const CloudTransferOptions& options)
{
    if (options.phase.isIsotropic()) return 0;
    if (options.phaseOrder >= 0) return options.phaseOrder;
    return 8;
}

int
CloudTransfer::directionCount(const CloudTransferOptions& options)
{
    if (options.directions != 0) return options.directions;
    if (options.phase.isIsotropic() || std::abs(options.phase.asymmetry()) <= 0.5) return 300;
    return 1000;
}

Acceleration
CloudTransfer::chooseAcceleration(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (options.accelerate) return *options.accelerate;
    // The thickest column's optical thickness along the vertical and the largest albedo, both
    // delta-M scaled as the sweeps see them.
    const int order = phaseOrderFor(options);
    const double f = options.phase.truncate(order).f, h = cloud.voxelSize();
    std::unordered_map<Coord, double> column;
    double omegaMax = 0.0, tauMax = 0.0;
    for (size_t i = 0; i < cloud.size(); ++i) {
        Coord c = cloud.voxels().coord(i);
        c[options.up] = 0;
        const double w = channelOf(cloud.albedo(), i, options.channel), scaled = 1.0 - w * f;
        double& tau = column[c];
        tau += double(cloud.extinction(i)) * h * scaled;
        tauMax = std::max(tauMax, tau);
        if (scaled > 0.0) omegaMax = std::max(omegaMax, w * (1.0 - f) / scaled);
    }
    if (!std::isfinite(tauMax)) return Acceleration::Anderson;
    // A ground of albedo rho sends back up rho times what the cloud lets through, and the cloud
    // reflects about that same fraction of it down again: one more loop, at most rho s.
    const double cloudAlone = omegaMax * tauMax / (tauMax + 2.0);
    const double rho = options.groundAlbedo.value_or(0.0);
    double slowest = cloudAlone + (1.0 - cloudAlone) * rho * cloudAlone;
    // Surfaces facing each other (a room) pass light back and forth: their albedo is the loop.
    if (options.surfaces) {
        const Attribute& a = options.surfaces->albedo();
        for (size_t s = 0; s < options.surfaces->size(); ++s) {
            slowest = std::max(slowest, double(channelOf(a, s, options.channel)));
        }
    }
    return slowest > 0.5 ? Acceleration::Anderson : Acceleration::None;
}

Coord
CloudTransfer::copiesFor(const Cloud& cloud, const CloudTransferOptions& options, size_t dirs)
{
    if (!options.periodic || options.minPeriod == 0 || cloud.size() == 0) return Coord(1);
    // Mean optical depth per voxel of the box (empty cells count as clear air).
    const Coord dim = cloud.voxels().bbox().dim();
    double depth = 0.0;
    for (float e : cloud.extinctionArray()) depth += double(e);
    depth *= cloud.voxelSize() / (double(dim.x()) * double(dim.y()) * double(dim.z()));
    return PeriodicBoundary::copies(dim, options.up, options.minPeriod, dirs, depth);
}

void
CloudTransfer::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!finished()) iterate(interrupt);
}

size_t
CloudTransfer::memoryEstimate(const Cloud& cloud, const CloudTransferOptions& options,
    int threads)
{
    const Coord copies = periodicCopies(cloud, options);
    const size_t tiles = size_t(copies.x()) * size_t(copies.y()) * size_t(copies.z());
    // A ground adds a layer of voxels under the copies' footprint.
    size_t footprint = 0;
    if (options.groundAlbedo) {
        const Coord dim = cloud.voxels().bbox().dim();
        footprint = 1;
        for (int k = 0; k < 3; ++k) {
            if (k != options.up) footprint *= size_t(dim[k]) * size_t(copies[k]);
        }
    }
    const size_t surfaces = options.surfaces ? options.surfaces->size() : 0;
    // A periodic box is solved filled (filledBox()).
    const size_t filled = options.periodic ? size_t(cloud.voxels().bbox().volume()) : cloud.size();
    const size_t n = filled * tiles + footprint + surfaces;
    const size_t t = size_t(std::max(threads, 1));
    const int order = phaseOrderFor(options);
    const size_t M = size_t(order + 1) * size_t(order + 1);
    const bool anderson = chooseAcceleration(cloud, options) == Acceleration::Anderson;
    size_t perVoxel = 4 + 4 + 4 + 8 + 4;            // kappa, omega, beam J, deposit, diffuse J
    perVoxel += 8 + (M > 1 ? 8 : 0);                // escape factor, alpha's excess of I_00
    perVoxel += SweepSchedule::bytesPerVoxel(true, false, false);   // orders, layouts
    perVoxel += 4 * 4;                              // kappa in each pattern's order
    perVoxel += 4 * M + 4 * M + 4;                  // moments, their source, the beam's source
    perVoxel += 4 * (4 * M + 4);                    // the sources in each pattern's order
    if (M > 1) perVoxel += 4 * 4;                   // and their Y_00 coefficient alone
    if (!cloud.emission().isZero()) perVoxel += 4 + 4 * 4;   // emission's source, and ordered
    perVoxel += size_t(Impl::kGroups) * 4 * M;      // gathered moments per group
    perVoxel += 8 * M;                              // their double sum
    perVoxel += t * (4 + 16 + 8);                   // per thread: slots, line state, 1 - e^-tau
    // A batch's two matrices and its I_00 sums, per thread (its tile of 16 rows is left out).
    if (M > 1) perVoxel += t * (2 * 2 * 4 * Impl::batchSize(n, M) + 4);
    if (options.diffusion) perVoxel += DiffusionAcceleration::bytes(1) + 8 + 4;   // + r, before
    if (anderson) {
        const size_t mixed = Impl::mixedMoments(int(M));
        perVoxel += 8 * mixed + AndersonMixer::bytes(mixed, options.andersonDepth);   // + x, G(x)
    }
    // The copies of a narrow periodic box, or the ground's layer added: coordinates,
    // extinction, the voxel copied, index.
    if (tiles > 1 || footprint > 0 || surfaces > 0 || filled > cloud.size()) {
        perVoxel += 12 + 4 + 4 + 8;
    }
    size_t bytes = n * perVoxel;
    // Surfaces: the voxel each solved one is (in each pattern's order too), and per surface
    // voxel its normal, albedo, area, emission, Z, direct and landed power, per group what lands.
    if (surfaces > 0) {
        bytes += n * 4 * 5 + surfaces * (12 + 4 + 8 * 5 + 8 * size_t(Impl::kGroups)
            + (anderson ? 8 : 0));
        if (anderson) bytes += AndersonMixer::bytes(surfaces, options.andersonDepth);
    }
    if (options.periodic) {
        // Light carried across the side faces: per direction, sense, face and layer, twice.
        const openvdb::CoordBBox box = cloud.voxels().bbox();
        const size_t layers = size_t(box.dim()[options.up]);   // copies stack sideways only
        const size_t dirs = DirectionSet::fromCount(directionCount(options)).size();
        const size_t faces = dirs * 2 * 6 * layers;
        bytes += faces * (8 + 8 + PeriodicBoundary::kBytesPerSlot);
        if (anderson) {
            bytes += 8 * faces + AndersonMixer::bytes(faces, options.andersonDepth);
        }
    }
    return bytes;
}

uint64_t
CloudTransfer::fingerprint() const
{
    const Impl& impl = *mImpl;
    uint64_t h = hashBytes("vdbrad solve-cloud", 18);
    const VoxelIndex& v = mCloud.voxels();
    h = hashBytes(v.coords().data(), v.size() * sizeof(openvdb::Coord), h);
    h = hashBytes(impl.kappa.data(), impl.kappa.size() * sizeof(float), h);
    h = hashBytes(impl.omega.data(), impl.omega.size() * sizeof(float), h);
    h = hashBytes(impl.deposited.data(), impl.deposited.size() * sizeof(double), h);
    h = hashBytes(impl.chi.data(), impl.chi.size() * sizeof(double), h);
    h = hashBytes(impl.phase.beam.data(), impl.phase.beam.size() * sizeof(float), h);
    const int64_t options[14] = {int64_t(directions().size()), mOptions.periodic ? 1 : 0,
        phaseOrderFor(mOptions), int64_t(*mOptions.accelerate), mOptions.andersonDepth, mOptions.up,
        impl.M, mCopies.x(), mCopies.y(), mCopies.z(), int64_t(mOptions.source),
        mQuadratureDegree, impl.flat[0] + 2 * impl.flat[1] + 4 * impl.flat[2],
        mOptions.diffusion ? 1 : 0};
    h = hashBytes(options, sizeof options, h);
    if (impl.ground) h = hashBytes(&impl.groundAlbedo, sizeof(double), h);
    if (impl.surfaces) h = impl.surfaces->hash(h);
    h = hashBytes(impl.emitSource.data(), impl.emitSource.size() * sizeof(float), h);
    h = hashBytes(impl.skyIn.data(), impl.skyIn.size() * sizeof(float), h);
    return h;
}

void
CloudTransfer::saveState(SolverState& state) const
{
    const Impl& impl = *mImpl;
    mIteration.save(state);
    const double budget[5] = {mBudget.incident, mBudget.albedo, mBudget.transmittance,
        mBudget.directTransmittance, mBudget.absorptance};
    state.put("budget", budget, 5);
    state.put("diffuseJ", impl.diffuseJ);
    state.put("moments", impl.moments);
    state.put("leftFace", impl.leftFace);
    if (impl.ground) {
        state.put("groundDiffuse", impl.groundDiffuse);
        state.put("groundReflected", &mBudget.groundReflected, 1);
    }
    if (impl.surfaces) {
        state.put("surfaceLanded", impl.surfaceLanded);
        state.put("surfaceAbsorptance", &mBudget.surfaceAbsorptance, 1);
    }
    if (!impl.skyIn.empty()) state.put("skyIncident", &impl.skyIncident, 1);
    if (impl.mixer) impl.mixer->save(state, "anderson.");
}

void
CloudTransfer::restoreState(const SolverState& state)
{
    Impl& impl = *mImpl;
    mIteration.restore(state);
    const std::vector<double> budget = state.get<double>("budget", 5);
    impl.diffuseJ = state.get<float>("diffuseJ", impl.diffuseJ.size());
    impl.moments = state.get<float>("moments", impl.moments.size());
    impl.leftFace = state.get<double>("leftFace", impl.leftFace.size());
    if (impl.ground) {
        impl.groundDiffuse = state.get<double>("groundDiffuse", impl.groundDiffuse.size());
        mBudget.groundReflected = state.get<double>("groundReflected", 1)[0];
    }
    if (impl.surfaces) {
        impl.surfaceLanded = state.get<double>("surfaceLanded", impl.surfaceLanded.size());
        mBudget.surfaceAbsorptance = state.get<double>("surfaceAbsorptance", 1)[0];
    }
    if (!impl.skyIn.empty()) impl.skyIncident = state.get<double>("skyIncident", 1)[0];
    const double emitted = impl.emitted + impl.mediumEmitted;
    const double total = impl.incident + impl.skyIncident + emitted;
    mBudget.emitted = emitted > 0.0 ? emitted / total : 0.0;
    mBudget.mediumEmitted = emitted > 0.0 ? impl.mediumEmitted / total : 0.0;
    mBudget.sky = impl.skyIncident > 0.0 ? impl.skyIncident / total : 0.0;
    if (impl.mixer) impl.mixer->restore(state, "anderson.");
    mBudget.incident = budget[0];
    mBudget.albedo = budget[1];
    mBudget.transmittance = budget[2];
    mBudget.directTransmittance = budget[3];
    mBudget.absorptance = budget[4];
}

std::vector<float>
CloudTransfer::Impl::perGivenVoxel(const std::vector<double>& values, size_t width, size_t given,
    const Coord& copies) const
{
    std::vector<float> out(given * width);
    if (!solved) {
        for (size_t e = 0; e < out.size(); ++e) out[e] = float(values[e] * outputScale);
        return out;
    }
    std::vector<double> sum(out.size(), 0.0);
    for (size_t i = 0; i < n; ++i) {
        if (copyOf[i] == GroundLayer::kGround) continue;
        for (size_t k = 0; k < width; ++k) sum[copyOf[i] * width + k] += values[i * width + k];
    }
    const double per = outputScale / (double(copies.x()) * double(copies.y()) * double(copies.z()));
    for (size_t e = 0; e < out.size(); ++e) out[e] = float(sum[e] * per);
    return out;
}

std::vector<float>
CloudTransfer::meanIntensity() const
{
    const Impl& impl = *mImpl;
    std::vector<double> J(impl.n);
    for (size_t i = 0; i < impl.n; ++i) J[i] = double(impl.diffuseJ[i] + impl.beamJ[i]);
    return impl.perGivenVoxel(J, 1, mCloud.size(), mCopies);
}

std::vector<float>
CloudTransfer::scatteredSource(int order) const
{
    const Impl& impl = *mImpl;
    if (order < 0) OPENVDB_THROW(openvdb::ValueError, "source order must be >= 0, got " << order);
    const int K = std::min(order, mOptions.phaseOrder);
    const size_t width = size_t((K + 1) * (K + 1)), M = size_t(impl.M);
    // The coefficients the next sweep would scatter (Impl::sources(): alpha omega0' chi_l'
    // I_lm), of the last sweep's moments: the same state as meanIntensity()'s.
    const std::vector<float> c = impl.sources().source;
    std::vector<double> v(impl.n * width);
    for (size_t i = 0; i < impl.n; ++i) {
        for (size_t k = 0; k < width; ++k) v[i * width + k] = double(c[i * M + k]);
    }
    return impl.perGivenVoxel(v, width, mCloud.size(), mCopies);
}

void
CloudTransfer::recordScattering(openvdb::GridBase& grid, int order) const
{
    ScatteredSource s;
    s.order = std::min(order, mOptions.phaseOrder);
    s.phase = mOptions.phase;
    s.deltaM = mOptions.phase.truncate(mOptions.phaseOrder).f;
    s.toSun = mImpl->toSun;
    s.sunIrradiance = mOptions.sunColour * mOptions.irradiance;
    s.periodic = mOptions.periodic;
    s.up = mOptions.up;
    s.record(grid);
}

std::vector<float>
CloudTransfer::surfaceRadiosity() const
{
    const Impl& impl = *mImpl;
    if (!impl.surfaces) return {};
    std::vector<float> B(impl.surfaces->size());
    for (size_t v = 0; v < B.size(); ++v) {
        // A voxel no line reaches (no area) shows its emission.
        B[v] = impl.surfaceArea[v] > 0.0
            ? float(impl.surfaceSends(v) * impl.surfaceNorm[v] * impl.outputScale)
            : impl.surfaces->emission(v);
    }
    return B;
}

const std::vector<double>&
CloudTransfer::surfaceArea() const
{
    return mImpl->surfaceArea;
}

std::vector<float>
CloudTransfer::groundIrradiance() const
{
    const Impl& impl = *mImpl;
    if (!impl.ground) return {};
    // The given box's ground; a cell of the copies' ground is the one a period away from it.
    const openvdb::CoordBBox box = mCloud.voxels().bbox();
    const GroundLayer given(box, mOptions.up);
    const Coord dim = box.dim();
    std::vector<double> sum(given.size(), 0.0);
    for (size_t c = 0; c < impl.ground->size(); ++c) {
        Coord ijk = impl.ground->coord(c);
        for (int k = 0; k < 3; ++k) {
            if (k != mOptions.up) ijk[k] = box.min()[k] + (ijk[k] - box.min()[k]) % dim[k];
        }
        sum[given.cell(ijk)] += impl.groundDirect[c] + impl.groundDiffuse[c];
    }
    const double per = impl.outputScale / double(impl.ground->size() / given.size());
    std::vector<float> E(given.size());
    for (size_t c = 0; c < E.size(); ++c) E[c] = float(sum[c] * per);
    return E;
}

openvdb::FloatGrid::Ptr
CloudTransfer::groundGrid(const std::string& name) const
{
    const std::vector<float> E = groundIrradiance();
    if (E.empty()) return nullptr;
    const GroundLayer layer(mCloud.voxels().bbox(), mOptions.up);
    openvdb::FloatGrid::Ptr g = openvdb::FloatGrid::create(0.f);
    g->setTransform(mCloud.transform().copy());
    g->setName(name);
    openvdb::FloatGrid::Accessor acc = g->getAccessor();
    for (size_t c = 0; c < E.size(); ++c) acc.setValueOn(layer.coord(c), E[c]);
    g->insertMeta("vdbrad:ground_albedo", openvdb::FloatMetadata(float(mImpl->groundAlbedo)));
    g->insertMeta("vdbrad:up", openvdb::Int32Metadata(mOptions.up));
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(iterationCount()));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

openvdb::GridBase::Ptr
CloudTransfer::grid(const std::string& name) const
{
    openvdb::FloatGrid::Ptr g = arrayToGrid(mCloud.voxels(), meanIntensity(), mCloud.transform(),
        name);
    g->insertMeta("vdbrad:albedo", openvdb::FloatMetadata(float(mBudget.albedo)));
    g->insertMeta("vdbrad:transmittance", openvdb::FloatMetadata(float(mBudget.transmittance)));
    g->insertMeta("vdbrad:absorptance", openvdb::FloatMetadata(float(mBudget.absorptance)));
    if (mImpl->ground) {
        g->insertMeta("vdbrad:ground_reflected",
            openvdb::FloatMetadata(float(mBudget.groundReflected)));
    }
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(iterationCount()));
    g->insertMeta(meta::kResidual, openvdb::FloatMetadata(float(mIteration.lastResidual())));
    g->insertMeta(meta::kDirections, openvdb::Int32Metadata(int(directions().size())));
    g->insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(mIteration.seconds())));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

std::string
CloudTransfer::describe() const
{
    std::ostringstream os;
    os << "cloud: " << withCommas(mCloud.size()) << " voxels, " << directions().size()
       << " directions (nearest to " << mOptions.directions << "), "
       << (mOptions.periodic ? "periodic" : "open") << " boundaries";
    if (mCopies != Coord(1)) {
        os << " (solved as " << mCopies.x() << " x " << mCopies.y() << " x " << mCopies.z()
           << " copies of the box)";
    }
    const FlatAxes& flat = mImpl->flat;
    if (flat[0] || flat[1] || flat[2]) {
        const char* axis = "xyz";
        os << " (one voxel deep along";
        for (int k = 0; k < 3; ++k) if (flat[size_t(k)]) os << ' ' << axis[k];
        os << ": swept across it)";
    }
    if (mOptions.phaseOrder > 0) os << ", phase order " << mOptions.phaseOrder;
    if (mQuadratureDegree > 0) {
        os << ", weights exact for harmonics to degree " << mQuadratureDegree;
    }
    if (mImpl->diffusion) os << ", diffusion acceleration";
    if (mOptions.accelerate == Acceleration::Anderson) os << ", Anderson acceleration";
    if (mOptions.source == VoxelSource::Constant) os << ", constant source per voxel";
    if (mImpl->ground) os << ", over a Lambertian ground of albedo " << mImpl->groundAlbedo;
    if (mImpl->surfaces) {
        os << ", with " << withCommas(mImpl->surfaces->size()) << " surface voxels";
    }
    if (!mOptions.sky.empty()) os << ", under " << mOptions.sky.describe();
    if (isRgb(mCloud, mOptions)) os << " (channel " << mOptions.channel << ")";
    return os.str();
}

} // namespace vdbrad
