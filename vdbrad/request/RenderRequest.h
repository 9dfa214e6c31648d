// RenderRequest: `vdbrad render` and vdbrad.render() described once: the options of a picture
// (renderImageOptions()), read into RenderOptions, the EXR pixel type and the PNG tone map.
#pragma once

#include "vdbrad/request/Request.h"

#include "vdbrad/render/ImageIO.h"
#include "vdbrad/render/Renderer.h"

#include <string>
#include <vector>

namespace vdbrad {

const std::vector<OptionSpec>& renderImageOptions();

/// What a render request asks for.
struct RenderRequest
{
    RenderOptions render;   ///< without the mesh: meshPath
    ExrPixel pixel = ExrPixel::Half;
    ToneMap tone;
    std::string png;        ///< the PNG preview's file; empty: none
    std::string meshPath;   ///< the mesh drawn in place of the voxels; empty: none
};

/// @throw OptionError for a malformed size, camera or colour
RenderRequest readRenderRequest(const Request& request);

} // namespace vdbrad
