// `vdbrad make`: build a canonical scene or cloud (grids/CanonicalGrids.h).
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "grids/CanonicalGrids.h"

namespace vdbrad {
namespace cli {

int
runMake(const Arguments& a)
{
    const std::string name = a.positional()[0], out = a.positional()[1];
    const grids::Builder* builder = grids::findBuilder(name);
    if (!builder) {
        std::vector<std::string> names;
        for (const auto& b : grids::builders()) names.push_back(b.name);
        std::string msg = "unknown scene '" + name + "'";
        if (auto s = suggest(name, names)) msg += "; did you mean '" + *s + "'?";
        else {
            msg += "; one of:";
            for (const auto& n : names) msg += " " + n;
        }
        throw UsageError(msg);
    }
    grids::BuildParams p;
    p.res = a.getInt("res");
    // An option not given keeps the field's negative "the scene's default"; the table has
    // refused negative values where the user typed them.
    auto optional = [&](const char* opt, float& field) {
        if (a.has(opt)) field = float(a.getFloat(opt));
    };
    optional("albedo", p.albedo);
    optional("emission", p.emission);
    optional("radius", p.radius);
    optional("height", p.height);
    optional("tau", p.tau);
    if (a.has("seed")) p.seed = unsigned(a.getInt("seed"));
    checkOutput(out, {}, true);

    ProgressInterrupter progress(a.flag("quiet"));
    VdbFile file;
    progress.start(("building " + name + " at " + std::to_string(p.res)).c_str());
    // Builder messages start with the scene's name already.
    file.grids = forFile("make", [&] { return builder->build(p); });
    progress.end();
    setCreator(file);
    writeOutput(file, out);
    return 0;
}

} // namespace cli
} // namespace vdbrad
