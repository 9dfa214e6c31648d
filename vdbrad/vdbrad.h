// vdbrad: voxel radiosity on sparse OpenVDB grids (Chatelier & Malgouyres, 2006).
// Umbrella header: the scene contract, I/O, meshes and the voxelizer, the solvers (surface
// radiosity, clouds, the Monte Carlo reference), output grids and the renderer. These headers
// and the ones they include are the installed API; the sweep internals (SweepSchedule,
// LineSweep, the vector clones, the visibility cache, ...) are not installed.
#pragma once

#include "vdbrad/Attribute.h"
#include "vdbrad/Cloud.h"
#include "vdbrad/CloudTransfer.h"
#include "vdbrad/DirectionSet.h"
#include "vdbrad/Errors.h"
#include "vdbrad/GridContract.h"
#include "vdbrad/GridIO.h"
#include "vdbrad/ImageIO.h"
#include "vdbrad/Mesh.h"
#include "vdbrad/MonteCarloSolver.h"
#include "vdbrad/OutputGrids.h"
#include "vdbrad/RadiositySolver.h"
#include "vdbrad/Renderer.h"
#include "vdbrad/Scene.h"
#include "vdbrad/SurfaceExtraction.h"
#include "vdbrad/Version.h"
#include "vdbrad/VoxelIndex.h"
#include "vdbrad/Voxelizer.h"
