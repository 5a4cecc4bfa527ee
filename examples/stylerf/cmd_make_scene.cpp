// stylerf make-scene -o DIR [--size 128] [--num-views 60]: render the built-in analytic scene as a
// Blender-format dataset with ground-truth depth (see lib/scene/make_scene.hpp for the layout).
#include <boost/program_options.hpp>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/error.hpp"
#include "lib/scene/make_scene.hpp"

namespace po = boost::program_options;

namespace {
// The library names its settings by field; two of them have other flag names here (--views and
// --supersample mean a view selection and content rays per feature block in the other commands).
[[noreturn]] void rethrow_with_flag(const stylerf::host::SettingError& e) {
  const std::string flag = e.field() == "views" ? "--num-views" : e.field() == "supersample" ? "--pixel-samples" : "--" + e.field();
  throw stylerf::host::Error(flag + " " + e.problem());
}

int run_make_scene(int argc, char** argv) {
  std::string out;
  stylerf::scene::MakeSceneOptions opt;
  po::options_description desc("stylerf make-scene -o DIR [options]");
  desc.add_options()("help,h", "show this help")("output,o", po::value(&out), "output directory (Blender format)")(
      "size", po::value(&opt.size)->default_value(opt.size), "image width and height in pixels")(
      "num-views", po::value(&opt.views)->default_value(opt.views), "number of views (every 10th to val, every 10th+5 to test)")(
      "radius", stylerf::cli::value_shown(&opt.radius), "camera distance from the origin")(
      "pixel-samples", po::value(&opt.supersample)->default_value(opt.supersample), "anti-aliasing: samples per pixel per axis")(
      "textured", po::bool_switch(&opt.textured), "noise-textured shapes on a floor, seen from above (for structure from motion)");
  stylerf::cli::apply_renamed_flags("make-scene", argc, argv, {{"--views", "--num-views"}, {"--supersample", "--pixel-samples"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || out.empty()) {
    stylerf::cli::print_help(std::cout, "make-scene", desc,
                             "Writes transforms_{train,val,test}.json, RGBA PNGs and depth EXRs (distance along\n"
                             "the unit pixel-centre ray, 0 on the background). Load it with any Blender-format loader.");
    return out.empty() && !vm.count("help") ? 2 : 0;
  }
  stylerf::scene::MakeSceneSummary s;
  try {
    s = stylerf::scene::make_scene(out, opt);
  } catch (const stylerf::host::SettingError& e) {
    rethrow_with_flag(e);
  }
  std::cout << "make-scene: wrote " << out << ": " << s.train << " train, " << s.val << " val, " << s.test
            << " test views at " << opt.size << "x" << opt.size << " in " << s.seconds << " s\n";
  return 0;
}
stylerf::cli::Register reg("make-scene", run_make_scene);
}  // namespace
