#include "vdbrad/request/RenderRequest.h"

#include "vdbrad/request/SharedOptions.h"

#include <cstdio>

namespace vdbrad {

const std::vector<OptionSpec>&
renderImageOptions()
{
    static const std::vector<OptionSpec> table = concat(options::scene(), {
        {"res", OptionType::String, "640x480", "1920x1080",
            "image size WIDTHxHEIGHT, each 1 to 16384"},
        {"camera", OptionType::String, "", "0.28,0.27,-0.8,0.28,0.27,0,0,1,0,40",
            "eye x,y,z, target x,y,z, up x,y,z, vertical fov (degrees), world units; "
            "default: looking along +z at the scene's bounding box, which it frames"},
        {"png", OptionType::String, "", "preview.png",
            "also write an 8-bit sRGB PNG, tone mapped (the 90th-percentile luminance "
            "of the scene's pixels maps to 0.8, then --exposure)"},
        {"exposure", OptionType::Float, "0", "1", "PNG exposure adjustment, in stops"},
        OptionSpec{"exr-type", OptionType::String, "half", "float", "EXR pixel type"}
            .oneOf({"half", "float"}),
        OptionSpec{"aa", OptionType::Int, "1", "3",
            "antialiasing: N x N samples per pixel"}.within(1, 16),
        {"mesh", OptionType::String, "", "room.obj",
            "surfaces: draw the mesh the scene was voxelised from (OBJ or PLY, as given "
            "to voxelize), shaded by the solved voxels around each point: exact "
            "outlines instead of voxel ones"},
        OptionSpec{"gather", OptionType::Int, "0", "256",
            "surfaces: final gather with this many rays per pixel sample from the point "
            "the camera sees (E + albedo x (exact direct light + mean reflected radiosity "
            "of what the rays hit): smooth where the voxels are not); 0: show the "
            "voxels' radiosity"}.within(0, 65536),
        OptionSpec{"direct-samples", OptionType::Int, "16", "64",
            "--gather and glossy surfaces: shadow rays per pixel sample for the direct "
            "light"}.within(1, 65536),
        OptionSpec{"glossy-rays", OptionType::Int, "32", "128",
            "glossy surfaces (solved with a `specular` grid): rays per pixel sample "
            "drawn from the lobe towards the camera, plus the lamps through the lobe: "
            "highlights; 0: the lobes' light the same from every direction"}
            .within(0, 65536),
        {"background", OptionType::String, "0,0,0", "0.2,0.3,0.5",
            "linear RGB seen where rays hit nothing, for a file solved without a sky (one "
            "solved under --sky, --sky-model or --environment shows that sky)"},
        OptionSpec{"extinction-scale", OptionType::Float, "1", "10",
            "clouds: multiplies the density grid, as for the cloud solve"}.above(0),
        options::density(),
        {"cloud-source", OptionType::String, "mean_intensity", "scatter",
            "clouds: the grid of mean radiance J; a solve's file also has its scattered "
            "light's moments (J_sh0, ...) and its sun, and the source is then the light in "
            "the camera's direction (else albedo x J)"},
        OptionSpec{"cloud-step", OptionType::Float, "0.5", "0.25",
            "clouds: voxels per step of the ray march through the trilinearly "
            "interpolated density and source"}.above(0).atMost(4),
        OptionSpec{"cloud-source-order", OptionType::Int, "-1", "2",
            "clouds: use the solve's scattered-light moments up to this harmonic order "
            "(at most what the file has; fewer: faster, smoother in angle); -1: all"}
            .within(-1, 16),
    });
    return table;
}

RenderRequest
readRenderRequest(const Request& r)
{
    RenderRequest q;
    RenderOptions& o = q.render;
    o.scene = options::sceneOptions(r);
    {
        // WIDTHxHEIGHT, or WIDTH,HEIGHT (a Python tuple).
        const std::string res = r.getString("res");
        int w = 0, h = 0;
        char tail = 0;
        if ((std::sscanf(res.c_str(), "%dx%d%c", &w, &h, &tail) != 2
                && std::sscanf(res.c_str(), "%d,%d%c", &w, &h, &tail) != 2)
            || w < 1 || h < 1 || w > 16384 || h > 16384) {
            r.fail(r.spell("res") + " must be WIDTHxHEIGHT, each in [1, 16384], got '" + res + "'");
        }
        o.width = w;
        o.height = h;
    }
    if (r.has("camera")) {
        const std::vector<double> c = r.numbers("camera", 10,
            "eye x,y,z, target x,y,z, up x,y,z, vertical fov in degrees");
        Camera cam;
        cam.eye = openvdb::Vec3d(c[0], c[1], c[2]);
        cam.target = openvdb::Vec3d(c[3], c[4], c[5]);
        cam.up = openvdb::Vec3d(c[6], c[7], c[8]);
        cam.fov = c[9];
        if (!(cam.fov > 0.0 && cam.fov < 180.0)) {
            r.fail(r.spell("camera") + ": the field of view must be in (0, 180) degrees");
        }
        o.camera = cam;
    }
    const std::vector<double> bg = r.numbers("background", 3, "r,g,b");
    o.background = openvdb::Vec3f(float(bg[0]), float(bg[1]), float(bg[2]));
    o.samplesPerPixel = r.getInt("aa");
    o.gather = r.getInt("gather");
    o.directSamples = r.getInt("direct-samples");
    o.glossyRays = r.getInt("glossy-rays");
    o.cloud.extinctionScale = float(r.getFloat("extinction-scale"));
    o.cloud.density = r.getString("density");
    o.cloudSource = r.getString("cloud-source");
    o.cloudStep = r.getFloat("cloud-step");
    o.cloudSourceOrder = r.getInt("cloud-source-order");
    q.pixel = r.choice<ExrPixel>("exr-type", {{"half", ExrPixel::Half}, {"float", ExrPixel::Float}});
    q.tone.exposureStops = r.getFloat("exposure");
    q.png = r.getString("png");
    q.meshPath = r.getString("mesh");
    return q;
}

} // namespace vdbrad
