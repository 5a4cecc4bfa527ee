// stylerf scene-info --scene DIR [--downsample N] [--ndc auto|on|off] [--view-dependence] [--compare-poses REF]:
// load a scene and print what was loaded and which effects are switched on (and how its poses agree with REF's).
#include <boost/program_options.hpp>
#include <chrono>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/pose_alignment.hpp"
#include "lib/scene/scene.hpp"

namespace po = boost::program_options;

namespace {
int run_scene_info(int argc, char** argv) {
  std::string dir, ndc = "auto";
  stylerf::scene::LoadOptions opt;
  bool cameras_only = false;
  std::string reference;
  po::options_description desc("stylerf scene-info --scene DIR [options]");
  desc.add_options()("help,h", "show this help")("scene", po::value(&dir), "scene directory (Blender, LLFF, COLMAP or nerfstudio format)")(
      "downsample", po::value(&opt.downsample)->default_value(1), "image downsample factor")(
      "ndc", po::value(&ndc)->default_value("auto"), "NDC rays: auto (from the data), on, off")(
      "view-dependence", po::bool_switch(&opt.view_dependence), "switch view-dependent colour on")(
      "cameras-only", po::bool_switch(&cameras_only), "read cameras and image sizes, not pixels")(
      "compare-poses", po::value(&reference),
      "a scene with the same image names: its poses against this one's, after a similarity alignment");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || dir.empty()) {
    stylerf::cli::print_help(std::cout, "scene-info", desc);
    return dir.empty() && !vm.count("help") ? 2 : 0;
  }
  opt.ndc = stylerf::scene::parse_switch(ndc, "--ndc");
  opt.load_images = !cameras_only;
  const auto t0 = std::chrono::steady_clock::now();
  auto s = stylerf::scene::load_scene(dir, opt);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << s.describe();
  const auto path = stylerf::scene::default_path(s, 8);
  std::cout << "  render path: " << (s.format.find("-forward") != std::string::npos || s.effects.ndc ? "spiral" : "orbit") << ", first camera at ("
            << path[0].c2w[0][3] << ", " << path[0].c2w[1][3] << ", " << path[0].c2w[2][3] << ")\n";
  std::cout << "  loaded in " << secs << " s\n";
  if (!reference.empty()) {
    auto ro = opt;
    ro.load_images = false;
    ro.ndc = stylerf::scene::Switch::automatic;
    const auto ref = stylerf::scene::load_scene(reference, ro);
    std::cout << "poses against " << reference << ": " << stylerf::scene::compare_poses(ref, s).describe() << "\n";
  }
  return 0;
}
stylerf::cli::Register reg("scene-info", run_scene_info);
}  // namespace
