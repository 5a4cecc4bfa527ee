// stylerf import --images DIR -o SCENE [options]: photos to a scene folder by running COLMAP
// (lib/scene/colmap_import.hpp), then the scene loaded as train-density will load it, and described.
#include <boost/program_options.hpp>
#include <chrono>
#include <iostream>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "lib/scene/colmap_import.hpp"
#include "lib/scene/pose_alignment.hpp"
#include "lib/scene/scene.hpp"

namespace po = boost::program_options;

namespace {

void print_report(const stylerf::scene::ImportReport& r, double seconds) {
  std::cout << "import: " << r.registered << " of " << r.images << " images registered (" << r.matcher
            << " matching), mean reprojection error " << r.mean_reprojection_error << " px, " << seconds
            << " s in all\n  phases:";
  for (const auto& [phase, secs] : r.phase_seconds) std::cout << " " << phase << " " << secs << " s;";
  std::cout << "\n";
  if (!r.left_out.empty()) {
    std::cout << "  left out by COLMAP (not in the scene):";
    for (const auto& n : r.left_out) std::cout << " " << n;
    std::cout << "\n";
  }
  for (const auto& n : r.notes) std::cout << "  note: " << n << "\n";
}

int run_import(int argc, char** argv) {
  stylerf::scene::ImportOptions o;
  std::string reference;
  po::options_description desc("stylerf import --images DIR -o SCENE [options]");
  bool multi = false;
  desc.add_options()("help,h", "show this help")("images", po::value(&o.images), "folder of photos, all one size")(
      "output,o", po::value(&o.out), "scene folder to write (images/, sparse/0/, colmap/)")(
      "camera-model", po::value(&o.camera_model)->default_value(o.camera_model),
      "COLMAP camera model (SIMPLE_RADIAL, OPENCV, PINHOLE, ...); images are undistorted after")(
      "multi-camera", po::bool_switch(&multi), "one camera per image instead of one shared camera")(
      "matcher", po::value(&o.matcher)->default_value(o.matcher),
      "auto (exhaustive up to 150 images, sequential beyond), exhaustive or sequential")(
      "max-image-size", po::value(&o.max_image_size)->default_value(0),
      "longest image side COLMAP works at and the scene gets (0: as given)")(
      "colmap", po::value(&o.colmap)->default_value(o.colmap), "the COLMAP executable")(
      "threads", po::value(&o.threads)->default_value(0), "COLMAP threads (0: all cores)")(
      "compare-poses", po::value(&reference), "a scene with the same image names: print how well the poses agree")(
      "force", po::bool_switch(&o.force), "replace an existing output folder");
  stylerf::cli::apply_renamed_flags("import", argc, argv, {{"--reference", "--compare-poses"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || o.images.empty() || o.out.empty()) {
    stylerf::cli::print_help(std::cout, "import", desc);
    return vm.count("help") ? 0 : 2;
  }
  o.single_camera = !multi;
  const auto t0 = std::chrono::steady_clock::now();
  const auto report = stylerf::scene::import_with_colmap(o, [](const std::string& line) { std::cout << line << "\n" << std::flush; });
  print_report(report, stylerf::cli::seconds_since(t0));
  stylerf::scene::LoadOptions lo;
  lo.load_images = false;
  const auto scene = stylerf::scene::load_scene(o.out, lo);
  std::cout << scene.describe();
  if (!reference.empty()) {
    const auto ref = stylerf::scene::load_scene(reference, lo);
    std::cout << "poses against " << reference << ": " << stylerf::scene::compare_poses(ref, scene).describe() << "\n";
  }
  std::cout << "wrote " << o.out << ": train it with `stylerf train-density --scene " << o.out << "`\n";
  return 0;
}

stylerf::cli::Register reg("import", run_import);
}  // namespace
