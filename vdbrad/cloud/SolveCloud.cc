#include "vdbrad/cloud/CloudTransferImpl.h"

namespace vdbrad {

namespace {

std::string
budgetLine(const CloudBudget& b, const CloudTransferOptions& options)
{
    std::ostringstream os;
    os << "albedo " << b.albedo << ", transmittance " << b.transmittance << " (direct "
       << b.directTransmittance << "), absorptance " << b.absorptance;
    if (options.groundAlbedo) os << ", reflected by the ground " << b.groundReflected;
    if (options.surfaces) {
        os << " (left the box), emitted by the surfaces " << b.emitted - b.mediumEmitted
           << ", absorbed by them " << b.surfaceAbsorptance;
    }
    if (b.mediumEmitted > 0.0) os << ", emitted by the medium " << b.mediumEmitted;
    if (b.sky > 0.0) os << "; the sky's share of the incident " << b.sky;
    os << "; balance " << b.balance();
    return os.str();
}

// iterateSolve(), framed as one progress step unless @a control reports each iteration.
void
iterateFramed(CloudTransfer& transfer, const SolveControl& control,
    openvdb::util::NullInterrupter* interrupt)
{
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("cloud transfer");
    iterateSolve(transfer, control, interrupt);
    if (framed) interrupt->end();
}

SolveStats
statsOf(const CloudTransfer& transfer)
{
    SolveStats stats;
    stats.directions = int(transfer.directions().size());
    stats.iterations = transfer.iterationCount();
    stats.residual = transfer.residuals().empty() ? 0.0 : transfer.residuals().back();
    stats.seconds = transfer.seconds();
    return stats;
}

// The scatteredSource() coefficient grids of @a J, from (n x width) values per channel.
template<typename ValueT>
openvdb::GridPtrVec
sourceGrids(const Cloud& cloud, const std::vector<ValueT>& c, size_t width, const std::string& J)
{
    openvdb::GridPtrVec grids;
    std::vector<ValueT> v(cloud.size());
    for (size_t k = 0; k < width; ++k) {
        for (size_t i = 0; i < v.size(); ++i) v[i] = c[i * width + k];
        grids.push_back(arrayToGrid(cloud.voxels(), v, cloud.transform(),
            ScatteredSource::gridName(J, int(k))));
    }
    return grids;
}

// Colours (an RGB albedo of the medium or of the surfaces, RGB lamps): light of each colour
// travels alone, so each channel is its own transfer (the medium's work three times over).
openvdb::GridBase::Ptr
solveCloudRgb(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* radiosity, openvdb::GridPtrVec* sources, int sourceOrder)
{
    if (!control.checkpoint.empty() || !control.resume.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoints are not supported for an RGB cloud or "
            "surface scene (three solves, one per channel)");
    }
    const Scene* scene = options.surfaces;
    std::vector<openvdb::Vec3f> J(cloud.size()), B(scene ? scene->size() : 0);
    openvdb::Vec3f albedo, transmittance, absorptance;
    SolveStats stats;
    double residual = 0.0;
    std::vector<openvdb::Vec3f> moments;
    size_t width = 0;
    std::optional<CloudTransfer> last;   // the blue channel's: the scattering's metadata
    for (int c = 0; c < 3; ++c) {
        CloudTransferOptions o = options;
        o.channel = c;
        last.reset();
        CloudTransfer& transfer = last.emplace(cloud, o, interrupt);
        iterateFramed(transfer, control, interrupt);
        const CloudBudget& b = transfer.budget();
        if (control.note) control.note("channel " + std::string(1, "rgb"[c]) + ": " + budgetLine(b, o));
        const std::vector<float> j = transfer.meanIntensity();
        const std::vector<float> r = scene ? transfer.surfaceRadiosity() : std::vector<float>();
        for (size_t i = 0; i < J.size(); ++i) J[i][c] = j[i];
        for (size_t v = 0; v < B.size(); ++v) B[v][c] = r[v];
        if (sources) {
            const std::vector<float> m = transfer.scatteredSource(sourceOrder);
            moments.resize(m.size());
            width = m.size() / cloud.size();
            for (size_t e = 0; e < m.size(); ++e) moments[e][c] = m[e];
        }
        albedo[c] = float(b.albedo);
        transmittance[c] = float(b.transmittance);
        absorptance[c] = float(b.absorptance);
        const SolveStats s = statsOf(transfer);
        stats.directions = s.directions;
        stats.iterations = std::max(stats.iterations, s.iterations);
        residual = std::max(residual, s.residual);
        stats.seconds += s.seconds;
    }
    stats.residual = residual;
    if (radiosity) {
        radiosity->reset();
        if (scene) *radiosity = makeRadiosityGrid(*scene, B, stats);
    }
    openvdb::Vec3SGrid::Ptr g = arrayToGrid(cloud.voxels(), J, cloud.transform(),
        "mean_intensity");
    g->insertMeta("vdbrad:albedo", openvdb::Vec3SMetadata(albedo));
    g->insertMeta("vdbrad:transmittance", openvdb::Vec3SMetadata(transmittance));
    g->insertMeta("vdbrad:absorptance", openvdb::Vec3SMetadata(absorptance));
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(stats.iterations));
    g->insertMeta(meta::kResidual, openvdb::FloatMetadata(float(stats.residual)));
    g->insertMeta(meta::kDirections, openvdb::Int32Metadata(stats.directions));
    g->insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(stats.seconds)));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    if (sources) {
        last->recordScattering(*g, sourceOrder);
        *sources = sourceGrids(cloud, moments, width, g->getName());
    }
    return g;
}

// @a slice's values repeated along @a axes over @a box: the whole medium's grid, its name,
// transform and metadata kept.
template<typename GridT>
typename GridT::Ptr
extended(const GridT& slice, const openvdb::CoordBBox& box, const std::array<bool, 3>& axes)
{
    typename GridT::Ptr whole = GridT::create(slice.background());
    whole->setTransform(slice.transform().copy());
    whole->setName(slice.getName());
    whole->setGridClass(slice.getGridClass());
    for (auto m = slice.beginMeta(); m != slice.endMeta(); ++m) {
        if (m->second) whole->insertMeta(m->first, *m->second);
    }
    auto acc = whole->getAccessor();
    openvdb::Coord lo, hi;
    for (auto it = slice.cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        for (int k = 0; k < 3; ++k) {
            lo[k] = axes[size_t(k)] ? box.min()[k] : c[k];
            hi[k] = axes[size_t(k)] ? box.max()[k] : c[k];
        }
        for (int x = lo.x(); x <= hi.x(); ++x) {
            for (int y = lo.y(); y <= hi.y(); ++y) {
                for (int z = lo.z(); z <= hi.z(); ++z) acc.setValue({x, y, z}, *it);
            }
        }
    }
    return whole;
}

openvdb::GridBase::Ptr
extendedGrid(const openvdb::GridBase::Ptr& slice, const openvdb::CoordBBox& box,
    const std::array<bool, 3>& axes)
{
    if (!slice) return slice;
    if (const auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(slice)) {
        return extended(*f, box, axes);
    }
    if (const auto v = openvdb::gridPtrCast<openvdb::Vec3SGrid>(slice)) {
        return extended(*v, box, axes);
    }
    OPENVDB_THROW(openvdb::TypeError, "grid '" << slice->getName() << "' of type "
        << slice->valueType() << " cannot be extended along a uniform axis");
}

} // namespace

std::unique_ptr<Cloud>
uniformSlice(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (!options.periodic || options.surfaces) return nullptr;
    const std::array<bool, 3> axes = uniformAxes(cloud, options.up);
    if (!(axes[0] || axes[1] || axes[2])) return nullptr;
    return std::make_unique<Cloud>(sliceCloud(cloud, axes));
}

openvdb::GridBase::Ptr
solveCloud(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::FloatGrid::Ptr* ground, openvdb::GridBase::Ptr* radiosity,
    openvdb::GridPtrVec* sources, int sourceOrder)
{
    const std::unique_ptr<Cloud> slice = uniformSlice(cloud, options);
    return solveCloud(cloud, slice.get(), options, interrupt, control, ground, radiosity,
        sources, sourceOrder);
}

openvdb::GridBase::Ptr
solveCloud(const Cloud& cloud, const Cloud* slice, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::FloatGrid::Ptr* ground, openvdb::GridBase::Ptr* radiosity,
    openvdb::GridPtrVec* sources, int sourceOrder)
{
    if (sources && !(sourceOrder >= 0 && sourceOrder <= ScatteredSource::kMaxOrder)) {
        OPENVDB_THROW(openvdb::ValueError, "the scattered source's order must be in [0, "
            << ScatteredSource::kMaxOrder << "], got " << sourceOrder);
    }
    if (slice) {
        const openvdb::CoordBBox box = cloud.voxels().bbox();
        std::array<bool, 3> axes{};
        for (int k = 0; k < 3; ++k) {
            axes[size_t(k)] = slice->voxels().bbox().dim()[k] < box.dim()[k];
        }
        openvdb::GridBase::Ptr J = solveCloud(*slice, options, interrupt, control, ground,
            radiosity, sources, sourceOrder);
        if (ground && *ground) {
            // The ground's layer lies under the box, one voxel below it along the vertical.
            *ground = openvdb::gridPtrCast<openvdb::FloatGrid>(extendedGrid(*ground, box, axes));
        }
        if (sources) {
            for (openvdb::GridBase::Ptr& g : *sources) g = extendedGrid(g, box, axes);
        }
        return extendedGrid(J, box, axes);
    }
    if (isRgb(cloud, options)) {
        if (ground) ground->reset();
        return solveCloudRgb(cloud, options, interrupt, control, radiosity, sources,
            sourceOrder);
    }
    CloudTransfer transfer(cloud, options, interrupt);
    iterateFramed(transfer, control, interrupt);
    if (control.note) control.note(budgetLine(transfer.budget(), options));
    if (ground) *ground = transfer.groundGrid();
    if (radiosity) {
        radiosity->reset();
        if (options.surfaces) {
            *radiosity = makeRadiosityGrid(*options.surfaces, transfer.surfaceRadiosity(),
                statsOf(transfer));
        }
    }
    openvdb::GridBase::Ptr J = transfer.grid();
    if (sources) {
        transfer.recordScattering(*J, sourceOrder);
        const std::vector<float> c = transfer.scatteredSource(sourceOrder);
        *sources = sourceGrids(cloud, c, c.size() / std::max<size_t>(1, cloud.size()),
            J->getName());
    }
    return J;
}

} // namespace vdbrad
