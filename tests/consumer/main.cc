// Builds a one-voxel scene through the installed headers and library; prints its voxel count.
#include <vdbrad/vdbrad.h>

#include <iostream>

int
main()
{
    openvdb::initialize();
    auto normal = openvdb::Vec3SGrid::create();
    normal->setName("normal");
    normal->tree().setValueOn(openvdb::Coord(1, 2, 3), openvdb::Vec3f(0, 0, 1));
    const vdbrad::Scene scene = vdbrad::buildScene({normal});
    std::cout << "vdbrad " << VDBRAD_VERSION_STRING << ": " << scene.size() << " voxel\n";
    return scene.size() == 1 ? 0 : 1;
}
