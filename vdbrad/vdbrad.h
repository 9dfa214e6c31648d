// vdbrad: voxel radiosity on sparse OpenVDB grids (Chatelier & Malgouyres, 2006).
// Umbrella header: the scene contract, I/O, output grids, meshes, the voxelizer and the renderer.
#pragma once

#include "vdbrad/Attribute.h"
#include "vdbrad/Cloud.h"
#include "vdbrad/Errors.h"
#include "vdbrad/GridContract.h"
#include "vdbrad/GridIO.h"
#include "vdbrad/ImageIO.h"
#include "vdbrad/Mesh.h"
#include "vdbrad/OutputGrids.h"
#include "vdbrad/Renderer.h"
#include "vdbrad/Scene.h"
#include "vdbrad/SurfaceExtraction.h"
#include "vdbrad/Version.h"
#include "vdbrad/VoxelIndex.h"
#include "vdbrad/Voxelizer.h"
