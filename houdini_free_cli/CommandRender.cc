// `vdbrad render`: a solved scene or cloud to an OpenEXR image and a PNG preview (Renderer;
// its options: vdbrad/request/RenderRequest.h).
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "vdbrad/request/RenderRequest.h"
#include "vdbrad/request/SurfaceRequest.h"
#include "vdbrad/vdbrad.h"

#include <cstdio>
#include <memory>

namespace vdbrad {
namespace cli {

int
runRender(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const RenderRequest request = readRenderRequest(a.request());
    RenderOptions o = request.render;
    const std::string& png = request.png;
    checkOutput(out, {in}, a.flag("overwrite"));
    if (!png.empty()) {
        if (isStdout(png)) throw UsageError("--png needs a file name");
        checkOutput(png, {in}, a.flag("overwrite"));
        if (png == out) throw UsageError("--png and the EXR output are the same file");
    }

    const std::string& meshPath = request.meshPath;
    if (!meshPath.empty()) {
        if (isStdin(meshPath)) throw UsageError("--mesh must be a file");
        // Mesh errors already start with the file name (and line): no label of our own.
        try {
            o.mesh = std::make_shared<const TriangleMesh>(readMesh(meshPath));
        } catch (const std::exception& e) {
            throw UserError(errorMessage(e));
        }
    }

    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    describeReading(a, label, file, o.scene.surface, o.cloud.density);
    // The sky and sun it was solved under: the background, and the gather's light.
    std::vector<std::string> lightWarnings;
    const OutsideLight light = solvedLight(file.grids, lightWarnings);
    o.sky = light.sky;
    o.sun = light.sun;
    for (const std::string& w : lightWarnings) warn(label, w);
    ProgressInterrupter progress(a.flag("quiet"));
    const Image image = forFile(label, [&] {
        progress.start("reading the scene");
        Renderer renderer(file.grids, o, &progress);
        progress.end();
        const std::string step = "rendering " + std::to_string(o.width) + "x"
            + std::to_string(o.height);
        progress.start(step.c_str());
        Image result = renderer.render(&progress);
        progress.end();
        return result;
    });
    for (const std::string& w : image.warnings) warn(label, w);
    // Both images are encoded before either is written, so an error leaves neither behind.
    const std::string exrBytes = forFile(outputLabel(out), [&] { return encodeExr(image, request.pixel); });
    const std::string pngBytes = png.empty() ? std::string()
        : forFile(png, [&] { return encodePng(image, request.tone); });
    writeBytes(exrBytes, out);
    if (!png.empty()) writeBytes(pngBytes, png);
    return 0;
}

} // namespace cli
} // namespace vdbrad
