// stylerf make-scene -o DIR [--size 128] [--views 60]: render the built-in analytic scene as a
// Blender-format dataset with ground-truth depth (see lib/scene/make_scene.hpp for the layout).
#include <boost/program_options.hpp>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "lib/scene/make_scene.hpp"

namespace po = boost::program_options;

namespace {
int run_make_scene(int argc, char** argv) {
  std::string out;
  stylerf::scene::MakeSceneOptions opt;
  po::options_description desc("stylerf make-scene -o DIR [options]");
  desc.add_options()("help,h", "show this help")("output,o", po::value(&out), "output directory (Blender format)")(
      "size", po::value(&opt.size)->default_value(opt.size), "image width and height in pixels")(
      "views", po::value(&opt.views)->default_value(opt.views), "number of views (every 10th to val, every 10th+5 to test)")(
      "radius", po::value(&opt.radius)->default_value(opt.radius), "camera distance from the origin")(
      "supersample", po::value(&opt.supersample)->default_value(opt.supersample), "samples per pixel per axis")(
      "textured", po::bool_switch(&opt.textured), "noise-textured shapes on a floor, seen from above (for structure from motion)");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || out.empty()) {
    std::cout << desc << "\nWrites transforms_{train,val,test}.json, RGBA PNGs and depth EXRs (distance along\n"
              << "the unit pixel-centre ray, 0 on the background). Load it with any Blender-format loader.\n";
    return out.empty() && !vm.count("help") ? 2 : 0;
  }
  auto s = stylerf::scene::make_scene(out, opt);
  std::cout << "make-scene: wrote " << out << ": " << s.train << " train, " << s.val << " val, " << s.test
            << " test views at " << opt.size << "x" << opt.size << " in " << s.seconds << " s\n";
  return 0;
}
stylerf::cli::Register reg("make-scene", "render the built-in analytic scene as a Blender-format dataset with depth",
                           run_make_scene);
}  // namespace
