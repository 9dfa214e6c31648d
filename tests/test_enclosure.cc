// Enclosure: the sparse block fill gives exactly the regions of a brute-force flood fill over every
// cell of the bounding box (the implementation it replaced: DenseRegions.h), on random scenes and
// on hand-built boxes with known answers.
#include "DenseRegions.h"
#include "vdbrad/sweep/Enclosure.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <string>
#include <vector>

using namespace vdbrad;
using openvdb::Coord;
using openvdb::Vec3f;

namespace {

// A set of surface voxels with a normal each (the last one given for a voxel wins).
struct Walls
{
    std::map<Coord, Vec3f> voxels;

    void add(const Coord& c, const Vec3f& n) { voxels[c] = n; }
    void remove(const Coord& c) { voxels.erase(c); }

    /// The one-voxel shell of [lo, hi], normals towards the box centre (@a inward) or away.
    void addBoxShell(const Coord& lo, const Coord& hi, bool inward)
    {
        for (int x = lo.x(); x <= hi.x(); ++x) for (int y = lo.y(); y <= hi.y(); ++y) {
            for (int z = lo.z(); z <= hi.z(); ++z) {
                if (x != lo.x() && x != hi.x() && y != lo.y() && y != hi.y() && z != lo.z()
                    && z != hi.z()) continue;
                // Sum of the outward face normals the voxel lies on (edges, corners: diagonal).
                Vec3f n(0.f);
                n[0] = x == lo.x() ? -1.f : x == hi.x() ? 1.f : 0.f;
                n[1] = y == lo.y() ? -1.f : y == hi.y() ? 1.f : 0.f;
                n[2] = z == lo.z() ? -1.f : z == hi.z() ? 1.f : 0.f;
                n.normalize();
                add(Coord(x, y, z), inward ? -n : n);
            }
        }
    }

    VoxelIndex index(std::vector<Vec3f>& normals) const
    {
        openvdb::MaskTree mask;
        for (const auto& v : voxels) mask.setValueOn(v.first);
        VoxelIndex index(mask);
        normals.resize(index.size());
        for (size_t i = 0; i < index.size(); ++i) normals[i] = voxels.at(index.coord(i));
        return index;
    }
};

struct Solved
{
    VoxelIndex index;
    std::vector<Vec3f> normals;
    Regions regions;
};

Solved
solve(const Walls& walls, LineType lines)
{
    Solved s;
    s.index = walls.index(s.normals);
    s.regions = findRegions(s.index, s.normals, lines);
    return s;
}

/// Region of the voxel at @a c.
uint32_t
regionAt(const Solved& s, const Coord& c)
{
    const int32_t i = s.index.find(c);
    EXPECT_GE(i, 0) << c;
    return i < 0 ? ~0u : s.regions.region[size_t(i)];
}

/// The sparse and the dense fill agree exactly on @a walls; returns the cavity count.
uint32_t
expectSameAsDense(const Walls& walls, LineType lines, const std::string& what)
{
    std::vector<Vec3f> normals;
    const VoxelIndex index = walls.index(normals);
    const Regions dense = test::denseRegions(index, normals, lines);
    const Regions sparse = findRegions(index, normals, lines);
    EXPECT_TRUE(dense.analysed) << what;
    EXPECT_EQ(sparse.analysed, dense.analysed) << what;
    EXPECT_EQ(sparse.cavities, dense.cavities) << what;
    EXPECT_EQ(sparse.region.size(), index.size()) << what;
    size_t differ = 0;
    for (size_t i = 0; i < index.size() && i < sparse.region.size(); ++i) {
        if (sparse.region[i] != dense.region[i] && differ++ < 3) {
            ADD_FAILURE() << what << ": voxel " << index.coord(i) << " normal " << normals[i]
                          << ": sparse region " << sparse.region[i] << ", dense "
                          << dense.region[i];
        }
    }
    EXPECT_EQ(differ, 0u) << what;
    return dense.cavities;
}

const char*
name(LineType lines)
{
    return lines == LineType::Naive ? "naive" : "standard";
}

Vec3f
randomNormal(std::mt19937& rng)
{
    std::normal_distribution<float> g;
    Vec3f n(g(rng), g(rng), g(rng));
    if (n.length() < 1e-3f) n = Vec3f(1.f, 0.f, 0.f);
    return n.unitSafe();
}

/// A random corner near an 8-grid boundary (coordinates 8k - 2 ... 8k + 1), negatives included.
Coord
nearGridLine(std::mt19937& rng)
{
    std::uniform_int_distribution<int> block(-3, 3), off(-2, 1);
    return Coord(8 * block(rng) + off(rng), 8 * block(rng) + off(rng), 8 * block(rng) + off(rng));
}

} // namespace

TEST(Enclosure, ClosedBoxInteriorIsOneCavityAndItsOutsideRegionZero)
{
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        // [-3, 9]^3 straddles the 8-grid: its walls lie in 8 leaves, its air in 2 blocks and more.
        Walls inward;
        inward.addBoxShell(Coord(-3), Coord(9), true);
        const Solved in = solve(inward, lines);
        EXPECT_TRUE(in.regions.analysed);
        EXPECT_EQ(in.regions.cavities, 1u) << name(lines);
        for (const uint32_t r : in.regions.region) EXPECT_EQ(r, 1u) << name(lines);

        Walls outward;
        outward.addBoxShell(Coord(-3), Coord(9), false);
        const Solved out = solve(outward, lines);
        EXPECT_TRUE(out.regions.analysed);
        EXPECT_EQ(out.regions.cavities, 0u) << name(lines);
        for (const uint32_t r : out.regions.region) EXPECT_EQ(r, 0u) << name(lines);
    }
}

TEST(Enclosure, DiagonalOnlyHoleClosesForStandardAndOpensForNaiveLines)
{
    // A closed box whose face x = 0 has a dent: (0, 5, 5) is air, plugged face-wise by (-1, 5, 5).
    // From the dent the outside is reached only diagonally, e.g. to (-1, 6, 5).
    for (const int shift : {0, 8, -16}) {   // the dent's cell on both sides of block boundaries
        Walls walls;
        const Coord o(shift, 3, -5);
        walls.addBoxShell(o, o + Coord(10), true);
        walls.remove(o + Coord(0, 5, 5));
        walls.add(o + Coord(-1, 5, 5), Vec3f(1.f, 0.f, 0.f));
        const Solved standard = solve(walls, LineType::Standard);
        EXPECT_EQ(standard.regions.cavities, 1u);
        EXPECT_EQ(regionAt(standard, o + Coord(10, 5, 5)), 1u);
        EXPECT_EQ(regionAt(standard, o + Coord(-1, 5, 5)), 1u);   // faces the dent: inside
        const Solved naive = solve(walls, LineType::Naive);
        EXPECT_EQ(naive.regions.cavities, 0u);
        for (const uint32_t r : naive.regions.region) EXPECT_EQ(r, 0u);
        expectSameAsDense(walls, LineType::Standard, "dent");
        expectSameAsDense(walls, LineType::Naive, "dent");
    }
}

TEST(Enclosure, OneCellHolesAtFacesEdgesAndCornersOpenAsTheLinesSee)
{
    // One shell voxel of a box removed: at a face centre it opens the box to both
    // connectivities; at an edge or a corner the hole touches the interior only diagonally, so the
    // box stays closed for standard lines.
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        for (const Coord& hole : {Coord(0, 4, 4), Coord(0, 0, 4), Coord(0, 0, 0)}) {
            Walls walls;
            walls.addBoxShell(Coord(0), Coord(8), true);
            walls.remove(hole);
            const Solved s = solve(walls, lines);
            const bool open = lines == LineType::Naive || hole == Coord(0, 4, 4);
            EXPECT_EQ(s.regions.cavities, open ? 0u : 1u) << name(lines) << " hole " << hole;
            EXPECT_EQ(regionAt(s, Coord(8, 4, 4)), open ? 0u : 1u) << name(lines) << hole;
            expectSameAsDense(walls, lines, "hole");
        }
    }
}

TEST(Enclosure, NestedBoxesGiveTwoCavitiesNumberedInVoxelOrder)
{
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        Walls walls;
        walls.addBoxShell(Coord(-20), Coord(20), true);   // outer room, seen from inside
        walls.addBoxShell(Coord(-6), Coord(5), false);    // a closed crate in it, seen from outside
        walls.addBoxShell(Coord(-4), Coord(3), true);     // a closed box in the crate
        const Solved s = solve(walls, lines);
        EXPECT_EQ(s.regions.cavities, 2u) << name(lines);
        const uint32_t room = regionAt(s, Coord(-20, 0, 0));
        const uint32_t inner = regionAt(s, Coord(-4, 0, 0));
        EXPECT_EQ(regionAt(s, Coord(-6, 0, 0)), room);   // the crate's outer faces see the room
        EXPECT_NE(room, inner);
        EXPECT_GE(room, 1u);
        EXPECT_GE(inner, 1u);
        // Numbered as first met in voxel (index) order.
        uint32_t seen = 0;
        for (const uint32_t r : s.regions.region) {
            EXPECT_LE(r, seen + 1);
            seen = std::max(seen, r);
        }
        expectSameAsDense(walls, lines, "nested");
    }
}

TEST(Enclosure, FrontsFollowTheNormalThroughThickWalls)
{
    // A wall 3 voxels thick between two closed rooms: a voxel facing into the wall finds its
    // front 3 steps away; 4 would be too far (region 0).
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        Walls walls;
        walls.addBoxShell(Coord(0), Coord(20, 8, 8), true);
        for (int x = 9; x <= 11; ++x) for (int y = 1; y < 8; ++y) for (int z = 1; z < 8; ++z) {
            walls.add(Coord(x, y, z), Vec3f(x < 10 ? 1.f : -1.f, 0.f, 0.f));
        }
        walls.add(Coord(9, 4, 4), Vec3f(1.f, 0.f, 0.f));     // 3 steps to the right room
        walls.add(Coord(11, 4, 4), Vec3f(-1.f, 0.f, 0.f));   // 3 steps to the left room
        walls.add(Coord(10, 4, 4), Vec3f(0.f, 1.f, 0.f));    // buried: no air within 3 steps
        const Solved s = solve(walls, lines);
        EXPECT_EQ(s.regions.cavities, 2u);
        const uint32_t left = regionAt(s, Coord(0, 4, 4)), right = regionAt(s, Coord(20, 4, 4));
        EXPECT_NE(left, right);
        EXPECT_EQ(regionAt(s, Coord(9, 4, 4)), right);
        EXPECT_EQ(regionAt(s, Coord(11, 4, 4)), left);
        EXPECT_EQ(regionAt(s, Coord(10, 4, 4)), 0u);
        expectSameAsDense(walls, lines, "thick wall");
    }
}

TEST(Enclosure, GapsAtBlockEdgesAndCornersOpenForNaiveLinesOnly)
{
    // A room that is exactly one 8^3 block, walled by the shell of [-1, 8]^3, with the shell's
    // edge column (8, 8, 0..7) or its corner (8, 8, 8) removed: the room and the empty block
    // beyond the gap touch only along an edge or at a corner, while the blocks beside the gap are
    // walls. Naive lines pass the gap, standard lines do not.
    // A wall voxel inside the room's block or inside the block beyond the gap (or both) makes
    // the pair meeting at the gap empty-empty, wall-empty or wall-wall.
    for (int variant = 0; variant < 8; ++variant) {
        const bool corner = variant & 1, roomWall = variant & 2, beyondWall = variant & 4;
        for (const Coord& o : {Coord(0), Coord(-16, 8, -24)}) {
            Walls walls;
            walls.addBoxShell(o + Coord(-1), o + Coord(8), true);
            if (corner) {
                walls.remove(o + Coord(8));
            } else {
                for (int z = 0; z < 8; ++z) walls.remove(o + Coord(8, 8, z));
            }
            if (roomWall) walls.add(o + Coord(2, 3, 4), Vec3f(0.f, 1.f, 0.f));
            if (beyondWall) walls.add(o + Coord(13, 12, corner ? 11 : 4), Vec3f(1.f, 0.f, 0.f));
            const std::string what = std::string(corner ? "corner gap" : "edge gap")
                + (roomWall ? ", wall in the room" : "") + (beyondWall ? ", wall beyond" : "");
            const Solved naive = solve(walls, LineType::Naive);
            EXPECT_EQ(naive.regions.cavities, 0u) << what;
            EXPECT_EQ(regionAt(naive, o + Coord(-1, 3, 3)), 0u) << what;
            const Solved standard = solve(walls, LineType::Standard);
            EXPECT_EQ(standard.regions.cavities, 1u) << what;
            EXPECT_EQ(regionAt(standard, o + Coord(-1, 3, 3)), 1u) << what;
            expectSameAsDense(walls, LineType::Naive, what);
            expectSameAsDense(walls, LineType::Standard, what);
        }
    }
}

TEST(Enclosure, ComponentsSplitInsideALeafJoinThroughTheirNeighbour)
{
    // A closed room of two blocks side by side, x in [0, 15]; a wall at y = 3 splits one of them
    // in two, and a wall voxel makes the other a leaf too: the two halves are one cavity only
    // through the other leaf's single component, which touches both across their common face.
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        for (const int split : {0, 8}) {
            Walls walls;
            walls.addBoxShell(Coord(-1), Coord(16, 8, 8), true);
            for (int x = split; x < split + 8; ++x) for (int z = 0; z < 8; ++z) {
                walls.add(Coord(x, 3, z), Vec3f(0.f, 1.f, 0.f));
            }
            walls.add(Coord(8 - split + 4, 5, 5), Vec3f(0.f, 0.f, 1.f));
            const Solved s = solve(walls, lines);
            EXPECT_EQ(s.regions.cavities, 1u) << name(lines) << " split " << split;
            const int far = split == 0 ? -1 : 16;   // shell voxels beside the split block
            EXPECT_EQ(regionAt(s, Coord(far, 1, 4)), 1u) << name(lines) << " split " << split;
            EXPECT_EQ(regionAt(s, Coord(far, 6, 4)), 1u) << name(lines) << " split " << split;
            expectSameAsDense(walls, lines, "split leaf");
        }
    }
}

TEST(Enclosure, CapOnBlocksLeavesLargeScenesUnanalysed)
{
    Walls walls;
    walls.addBoxShell(Coord(0), Coord(9), true);   // cells 0..9: blocks -1..2, 4^3 of them
    std::vector<Vec3f> normals;
    const VoxelIndex index = walls.index(normals);
    EXPECT_EQ(regionBlocks(index), 64u);
    EXPECT_EQ(regionBlocks(VoxelIndex()), 0u);
    EXPECT_GE(regionsBytes(index), 4u * 64u);
    const Regions capped = findRegions(index, normals, LineType::Naive, 63);
    EXPECT_FALSE(capped.analysed);
    EXPECT_EQ(capped.cavities, 0u);
    EXPECT_EQ(capped.region, std::vector<uint32_t>(index.size(), 0u));
    const Regions fits = findRegions(index, normals, LineType::Naive, 64);
    EXPECT_TRUE(fits.analysed);
    EXPECT_EQ(fits.cavities, 1u);
    const Regions none = findRegions(VoxelIndex(), {}, LineType::Naive);
    EXPECT_FALSE(none.analysed);
    EXPECT_TRUE(none.region.empty());
}

TEST(Enclosure, RandomWallsMatchTheDenseFill)
{
    // Random voxel soups from sparse to dense (many small cavities), in boxes straddling 8-grid
    // lines at negative and positive coordinates, with random normals.
    std::mt19937 rng(2024);
    size_t cavities = 0, scenes = 0;
    for (int trial = 0; trial < 120; ++trial) {
        const Coord lo = nearGridLine(rng);
        std::uniform_int_distribution<int> size(2, 24);
        const Coord hi = lo + Coord(size(rng), size(rng), size(rng));
        const float density = std::uniform_real_distribution<float>(0.15f, 0.75f)(rng);
        std::bernoulli_distribution on(density);
        Walls walls;
        for (int x = lo.x(); x <= hi.x(); ++x) for (int y = lo.y(); y <= hi.y(); ++y) {
            for (int z = lo.z(); z <= hi.z(); ++z) {
                if (on(rng)) walls.add(Coord(x, y, z), randomNormal(rng));
            }
        }
        if (walls.voxels.empty()) continue;
        for (const LineType lines : {LineType::Naive, LineType::Standard}) {
            cavities += expectSameAsDense(walls, lines,
                std::string("random walls ") + std::to_string(trial) + " " + name(lines));
            ++scenes;
            if (HasFailure()) return;
        }
    }
    // The scenes must exercise cavities at all, and a 3D checkerboard's many components below.
    EXPECT_GT(cavities, 100u);
    EXPECT_EQ(scenes, 240u);
}

TEST(Enclosure, RandomBlockScaleWallsMatchTheDenseFill)
{
    // Scenes made of whole 8^3 blocks: empty, solid, solid with a few cells cut out, or random,
    // so that empty blocks and components meet wall blocks across faces, edges and corners.
    std::mt19937 rng(4242);
    size_t cavities = 0;
    for (int trial = 0; trial < 60; ++trial) {
        std::uniform_int_distribution<int> at(-3, 1);
        const Coord base(8 * at(rng), 8 * at(rng), 8 * at(rng));
        const float solid = std::uniform_real_distribution<float>(0.3f, 0.7f)(rng);
        Walls walls;
        for (auto b = openvdb::CoordBBox(Coord(0), Coord(3)).beginXYZ(); b; ++b) {
            const float u = std::uniform_real_distribution<float>(0.f, 1.f)(rng);
            if (u > solid + 0.1f) continue;                         // empty block
            const bool random = u > solid;                          // random cells
            const Coord origin = base + (*b << 3);
            for (auto c = openvdb::CoordBBox(origin, origin + Coord(7)).beginXYZ(); c; ++c) {
                if (random && std::bernoulli_distribution(0.5)(rng)) continue;
                walls.add(*c, randomNormal(rng));
            }
            const int cuts = std::uniform_int_distribution<int>(0, 3)(rng);
            std::uniform_int_distribution<int> cell(0, 7);
            for (int c = 0; c < cuts; ++c) {
                walls.remove(origin + Coord(cell(rng), cell(rng), cell(rng)));
            }
        }
        if (walls.voxels.empty()) continue;
        for (const LineType lines : {LineType::Naive, LineType::Standard}) {
            cavities += expectSameAsDense(walls, lines,
                std::string("block scale ") + std::to_string(trial) + " " + name(lines));
            if (HasFailure()) return;
        }
    }
    EXPECT_GT(cavities, 50u);
}

TEST(Enclosure, RandomBoxesWithHolesMatchTheDenseFill)
{
    // Nested and overlapping box shells of random sizes near 8-grid lines, with one-cell holes at
    // random face, edge and corner cells, dents closed face-wise only, and random normals on
    // some voxels.
    std::mt19937 rng(77);
    size_t cavities = 0, open = 0;
    for (int trial = 0; trial < 150; ++trial) {
        Walls walls;
        const int boxes = std::uniform_int_distribution<int>(1, 4)(rng);
        for (int b = 0; b < boxes; ++b) {
            const Coord lo = nearGridLine(rng);
            std::uniform_int_distribution<int> size(2, 14);
            const Coord hi = lo + Coord(size(rng), size(rng), size(rng));
            walls.addBoxShell(lo, hi, std::bernoulli_distribution(0.6)(rng));
            const int holes = std::uniform_int_distribution<int>(0, 2)(rng);
            for (int h = 0; h < holes; ++h) {
                // A shell cell: pick each coordinate at a side, or inside, so that the hole
                // lands on a face (1 side), an edge (2) or a corner (3).
                Coord c;
                const int sides = std::uniform_int_distribution<int>(1, 3)(rng);
                std::vector<int> axes = {0, 1, 2};
                std::shuffle(axes.begin(), axes.end(), rng);
                for (int k = 0; k < 3; ++k) {
                    const int a = axes[size_t(k)];
                    if (k < sides) {
                        c[a] = std::bernoulli_distribution(0.5)(rng) ? lo[a] : hi[a];
                    } else {
                        c[a] = std::uniform_int_distribution<int>(lo[a] + 1,
                            std::max(lo[a] + 1, hi[a] - 1))(rng);
                    }
                }
                walls.remove(c);
                if (sides == 1 && std::bernoulli_distribution(0.5)(rng)) {
                    // Plug the hole from outside: closed for standard lines, open for naive.
                    Coord plug = c;
                    const int a = axes[0];
                    plug[a] += c[a] == lo[a] ? -1 : 1;
                    walls.add(plug, randomNormal(rng));
                }
            }
        }
        // A few random normals: fronts into walls, along edges, out of the boxes.
        for (auto& v : walls.voxels) {
            if (std::bernoulli_distribution(0.1)(rng)) v.second = randomNormal(rng);
        }
        for (const LineType lines : {LineType::Naive, LineType::Standard}) {
            const uint32_t k = expectSameAsDense(walls, lines,
                std::string("boxes ") + std::to_string(trial) + " " + name(lines));
            cavities += k;
            open += k == 0;
            if (HasFailure()) return;
        }
    }
    EXPECT_GT(cavities, 100u);
    EXPECT_GT(open, 20u);
}

TEST(Enclosure, CheckerboardsAndFarApartObjectsMatchTheDenseFill)
{
    // A 3D checkerboard: every air cell its own component for standard lines (256 per leaf: the
    // cell -> component tables), one for naive lines. Then two closed boxes 200 cells apart, so
    // that most blocks hold no wall.
    for (const LineType lines : {LineType::Naive, LineType::Standard}) {
        Walls board;
        for (int x = -9; x <= 9; ++x) for (int y = -9; y <= 9; ++y) for (int z = -9; z <= 9; ++z) {
            const bool border = std::abs(x) == 9 || std::abs(y) == 9 || std::abs(z) == 9;
            if (border || ((x + y + z) & 1) == 0) board.add(Coord(x, y, z), Vec3f(0.f, 0.f, 1.f));
        }
        const uint32_t k =
            expectSameAsDense(board, lines, std::string("checkerboard ") + name(lines));
        EXPECT_EQ(k, lines == LineType::Standard ? 17u * 17u * 17u / 2u : 1u);

        Walls apart;
        apart.addBoxShell(Coord(-205, 0, 0), Coord(-195, 10, 7), true);
        apart.addBoxShell(Coord(3, 3, 3), Coord(9, 9, 9), true);
        apart.addBoxShell(Coord(-5, 0, 0), Coord(12, 12, 12), false);
        EXPECT_EQ(expectSameAsDense(apart, lines, std::string("apart ") + name(lines)), 2u);
    }
}
