// vdbrad: voxel radiosity on sparse OpenVDB grids (Chatelier & Malgouyres, 2006).
// Umbrella header: the scene contract, I/O and output grids.
#pragma once

#include "vdbrad/Attribute.h"
#include "vdbrad/Cloud.h"
#include "vdbrad/Errors.h"
#include "vdbrad/GridContract.h"
#include "vdbrad/GridIO.h"
#include "vdbrad/OutputGrids.h"
#include "vdbrad/Scene.h"
#include "vdbrad/SurfaceExtraction.h"
#include "vdbrad/Version.h"
#include "vdbrad/VoxelIndex.h"
