// `vdbrad render`: a solved scene or cloud to an OpenEXR image and a PNG preview (Renderer).
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "vdbrad/vdbrad.h"

#include <cstdio>
#include <memory>

namespace vdbrad {
namespace cli {

int
runRender(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    RenderOptions o;
    o.scene = sceneOptions(a);
    {
        const std::string res = a.getString("res");
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(res.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 1 || h < 1
            || w > 16384 || h > 16384) {
            throw UsageError("--res must be WIDTHxHEIGHT, each in [1, 16384], got '" + res + "'");
        }
        o.width = w;
        o.height = h;
    }
    if (a.has("camera")) {
        const std::vector<double> c = numberList(a, "camera", 10,
            "eye x,y,z, target x,y,z, up x,y,z, vertical fov in degrees");
        Camera cam;
        cam.eye = openvdb::Vec3d(c[0], c[1], c[2]);
        cam.target = openvdb::Vec3d(c[3], c[4], c[5]);
        cam.up = openvdb::Vec3d(c[6], c[7], c[8]);
        cam.fov = c[9];
        if (!(cam.fov > 0.0 && cam.fov < 180.0)) {
            throw UsageError("--camera: the field of view must be in (0, 180) degrees");
        }
        o.camera = cam;
    }
    const std::vector<double> bg = numberList(a, "background", 3, "r,g,b");
    o.background = openvdb::Vec3f(float(bg[0]), float(bg[1]), float(bg[2]));
    o.samplesPerPixel = a.getInt("aa");
    o.gather = a.getInt("gather");
    o.directSamples = a.getInt("direct-samples");
    o.glossyRays = a.getInt("glossy-rays");
    o.cloud.extinctionScale = float(a.getFloat("extinction-scale"));
    o.cloud.density = a.getString("density");
    o.cloudSource = a.getString("cloud-source");
    const ExrPixel pixel = choice<ExrPixel>(a, "exr-type",
        {{"half", ExrPixel::Half}, {"float", ExrPixel::Float}});
    ToneMap tone;
    tone.exposureStops = a.getFloat("exposure");
    const std::string png = a.getString("png");
    checkOutput(out, {in}, a.flag("overwrite"));
    if (!png.empty()) {
        if (isStdout(png)) throw UsageError("--png needs a file name");
        checkOutput(png, {in}, a.flag("overwrite"));
        if (png == out) throw UsageError("--png and the EXR output are the same file");
    }

    const std::string meshPath = a.getString("mesh");
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
    const std::string exrBytes = forFile(outputLabel(out), [&] { return encodeExr(image, pixel); });
    const std::string pngBytes = png.empty() ? std::string()
        : forFile(png, [&] { return encodePng(image, tone); });
    writeBytes(exrBytes, out);
    if (!png.empty()) writeBytes(pngBytes, png);
    return 0;
}

} // namespace cli
} // namespace vdbrad
