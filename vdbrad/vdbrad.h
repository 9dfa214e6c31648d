// vdbrad: voxel radiosity on sparse OpenVDB grids (Chatelier & Malgouyres, 2006).
// Umbrella header: the scene contract, I/O, meshes and the voxelizer, the solvers (surface
// radiosity, clouds, the Monte Carlo reference), output grids and the renderer, and the requests hosts describe each command with. These headers
// and the ones they include are the installed API; the sweep internals (SweepSchedule,
// LineSweep, the vector clones, the visibility cache, ...) are not installed.
#pragma once

#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/core/Attribute.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/core/GridIO.h"
#include "vdbrad/core/ProcessInfo.h"
#include "vdbrad/core/Version.h"
#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/Voxelizer.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/render/ImageIO.h"
#include "vdbrad/render/Renderer.h"
#include "vdbrad/request/CloudRequest.h"
#include "vdbrad/request/RenderRequest.h"
#include "vdbrad/request/SurfaceRequest.h"
#include "vdbrad/request/VoxelizeRequest.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/scene/Sun.h"
#include "vdbrad/scene/SurfaceExtraction.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/sweep/DirectionSet.h"
