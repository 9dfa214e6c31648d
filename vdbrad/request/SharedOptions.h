// SharedOptions: the option groups several requests declare alike (the scene contract's
// options; iterations, acceleration, checkpoints, threads and memory), and their reading.
#pragma once

#include "vdbrad/request/Request.h"

#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/scene/Sun.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include <string>
#include <vector>

namespace vdbrad {
namespace options {

/// --surface, --albedo, --separation, --roughness: how a file's grids become surface voxels.
std::vector<OptionSpec> scene();
SceneOptions sceneOptions(const Request& request);

/// The fog volume's grid (--density).
OptionSpec density();
/// --directions of the surface solve.
OptionSpec directions();
/// --accelerate (solve) and --anderson-depth.
OptionSpec accelerate();
OptionSpec andersonDepth();
/// --checkpoint FILE, --checkpoint-every K, --resume FILE.
std::vector<OptionSpec> checkpoints();
/// --up: the vertical axis the sun's angles are measured from.
OptionSpec up();
/// --sky, --sky-model, --turbidity, --environment, --environment-rotation: light from outside.
std::vector<OptionSpec> sky();
/// @brief The sky @a request asks for (empty: none), one at a time: --sky, --sky-model clear
/// at @a sun's position and irradiance (needs one) over a ground of @a groundAlbedo, or
/// --environment (turned about @a up; a sun found in the map is the result's sun()).
/// @throw OptionError for contradictions, an unreadable map
Sky skyOf(const Request& request, const std::optional<Sun>& sun, double groundAlbedo, int up);
/// --threads and --max-memory.
std::vector<OptionSpec> resources();

/// @brief The checkpoint options of @a request set in @a control (saved only by rank 0 of
/// @a rank), checked together.
/// @throw OptionError where they contradict each other
void setCheckpoints(const Request& request, int rank, SolveControl& control);

/// "vdbrad.solve_cloud()" or "`vdbrad solve-cloud`": another command, as @a request's host
/// names it in a message.
std::string spellCommand(const Request& request, const std::string& command);

} // namespace options
} // namespace vdbrad
