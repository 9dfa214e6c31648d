// CloudShading: a solved cloud as a camera sees it, by ray marching through trilinear fields.
//
// Voxels hold numbers at their centres; drawing each as a cube of constant extinction and
// source shows blocks and stripes wherever the cloud is a few voxels across. Here the
// extinction and the emission density j = sigma' S are interpolated trilinearly between voxel
// centres (a voxel outside the medium counts as 0 for both, so edges fade over one voxel
// instead of stepping). Along any line a trilinear field is a cubic inside each dual cell (the
// cube between eight voxel centres), so the camera ray is walked cell by cell (a 3D DDA over
// the lattice of centres) and each piece, in steps of at most `step` voxels, gets its optical
// depth and mean emission density exactly from two Gauss points, and the exact exponential
// for a source constant over the step. The interpolated density integrates to the voxels' own
// (a tent of unit area per voxel), and no step straddles a cell face, where the fields bend.
//
// The source is what the solve found in the direction of the eye (ScatteredSource.h): the
// multiple-scattered light from the solved harmonic moments, plus the sun's first scattering
// with the full phase function, its transmittance from a shadow ray walked from each voxel
// centre through the same trilinear field (its optical depth exact; wrapping around a
// periodic box), plus the medium's
// own emission; all in the delta-M scaled problem the solve solved. The source depends on the
// view only through the direction of the eye, which across one voxel changes by a voxel over
// the eye's distance: it is evaluated once per voxel for the direction from the voxel's centre
// to the eye (aim()), and interpolated like the rest. A file solved without the moments (or J
// made by hand) gets the isotropic source albedo x J, the sun's light within it.
#pragma once

#include "vdbrad/cloud/ScatteredSource.h"
#include "vdbrad/core/Attribute.h"
#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/scene/Cloud.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

class CloudShading
{
public:
    /// Voxels per step of the camera rays and shadow rays, by default.
    static constexpr double kDefaultStep = 0.5;

    /// @brief Read the source of @a cloud (not copied: it must outlive this) from its solved
    /// mean-intensity grid @a J (null: the cloud only absorbs) and the scattering moments
    /// in @a grids, and march the shadow rays.
    /// @param step      voxels per march step, in (0, 4]
    /// @param maxOrder  the highest order of the moments used (-1: all the file has)
    /// @param blockers  if not null, voxels on the cloud's transform that stop the sun's light
    ///                  (the surfaces of a fog solved inside a scene: FogSurfaces.h); not
    ///                  copied
    /// @throw openvdb::ValueError for a bad step or broken scattering metadata
    ///        (ScatteredSource::read()); openvdb::TypeError for J not float or vec3s
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop
    CloudShading(const Cloud& cloud, const openvdb::GridBase::ConstPtr& J,
        const openvdb::GridPtrVec& grids, double step = kDefaultStep, int maxOrder = -1,
        const VoxelIndex* blockers = nullptr, openvdb::util::NullInterrupter* interrupt = nullptr);

    /// @brief Evaluate each voxel's source towards the world point @a eye (march() needs it).
    void aim(const openvdb::Vec3d& eye, openvdb::util::NullInterrupter* interrupt = nullptr);

    /// Whether the cloud sends any light (else it only absorbs).
    bool emits() const { return mEmits; }
    /// Whether the file had the solve's moments (else: the isotropic source albedo x J).
    bool directional() const { return mScattering.has_value(); }

    using Accessor = VoxelIndex::Accessor;
    /// @brief Along the world ray (@a eye, unit @a dir) over world distances [t0, t1]: add
    /// T x the light the cloud sends towards the eye to @a L (radiosity units: pi x radiance,
    /// as the renderer's pixels) and multiply @a T by the transmittance, per channel; stops
    /// early once every channel of T is below @a opaque. @a acc: an accessor of the cloud's
    /// voxel index (one per thread).
    void march(Accessor& acc, const openvdb::Vec3d& eye, const openvdb::Vec3d& dir, double t0,
        double t1, openvdb::Vec3d& L, openvdb::Vec3d& T, double opaque) const;

    /// Per voxel: delta-M scaled extinction per world unit, and the transmittance of the path
    /// from its centre to the sun (1 without a sun), per channel.
    const std::vector<openvdb::Vec3f>& extinction() const { return mSigma; }
    const std::vector<openvdb::Vec3f>& sunTransmittance() const { return mSunT; }

private:
    // The fields at the corners of one dual cell (CloudShading.cc).
    struct Cell
    {
        openvdb::Vec3d sigma[8], emit[8];
    };
    template<bool Wrap>
    bool loadCell(Accessor& acc, const openvdb::Coord& base, Cell& cell, bool emit) const;
    template<bool Wrap, typename SegmentF>
    void walk(Accessor& acc, const openvdb::Vec3d& o, const openvdb::Vec3d& d, double ta,
        double tb, bool emit, bool empty, SegmentF&& segment) const;
    void traceShadows(const VoxelIndex* blockers, openvdb::util::NullInterrupter* interrupt);

    const Cloud& mCloud;
    std::optional<ScatteredSource> mScattering;
    std::vector<Attribute> mMoments;        // per coefficient (directional)
    Attribute mJ;                           // the isotropic source's J (not directional)
    bool mHasJ = false, mEmits = false;
    double mStep = kDefaultStep;
    openvdb::CoordBBox mBox;                // the voxels' index bounds
    std::vector<openvdb::Vec3f> mSigma, mSunT;
    std::vector<openvdb::Vec3f> mEmit;      // pi sigma' S towards the eye (aim())
};

} // namespace vdbrad
