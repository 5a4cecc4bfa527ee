#include "examples/stylerf/command_index.hpp"

namespace stylerf::cli {

const std::vector<std::string>& workflow_groups() {
  static const std::vector<std::string> groups = {"get a scene", "train", "stylise and render", "evaluate", "tools"};
  return groups;
}

const std::vector<CommandInfo>& command_index() {
  static const std::vector<CommandInfo> index = {
      {"make-scene", "get a scene", "render the built-in analytic scene as a Blender-format dataset with depth",
       {"stylerf make-scene -o scene --size 128 --num-views 48", "stylerf make-scene -o photos_scene --textured"}},
      {"import", "get a scene", "photos to a scene folder, by running COLMAP (features, matching, mapper, undistortion)",
       {"stylerf import --images photos -o scene", "stylerf import --images photos -o scene --max-image-size 1600"}},
      {"scene-info", "get a scene", "load a scene and print cameras, box, near/far and the effects switched on",
       {"stylerf scene-info --scene scene", "stylerf scene-info --scene scene --compare-poses reference_scene"}},
      {"run", "train", "the whole pipeline: density, features, style, then videos, mix sheet and consistency",
       {"stylerf run --scene scene --styles styles -o out --minutes 90",
        "stylerf run --scene scene --styles styles -o out --stage-iters 700,280,90 --check"}},
      {"train-density", "train", "density stage: train TensoRF VM grids on a scene's RGB images",
       {"stylerf train-density --scene scene -o density.ckpt --minutes 10"}},
      {"train-features", "train", "feature stage: a VGG feature grid and decoder over a density checkpoint's geometry",
       {"stylerf train-features --density density.ckpt -o features.ckpt --minutes 30"}},
      {"train-style", "train", "style stage: SICT + DST over a feature checkpoint, many style images",
       {"stylerf train-style --features features.ckpt --styles styles -o style.ckpt --minutes 45"}},
      {"stylize", "stylise and render", "zero-shot stylisation: any style image, interpolation, 3D region composition",
       {"stylerf stylize --ckpt style.ckpt --style starry.jpg --views path -o out",
        "stylerf stylize --ckpt style.ckpt --style a.jpg --style b.jpg --mix 0.5,0.5 --views test --max-views 3 -o out"}},
      {"view", "stylise and render",
       "a live viewer in the browser: orbit the scene, drop any picture to restyle it, mix two styles, 3D regions",
       {"stylerf view --ckpt style.ckpt --styles styles --open",
        "stylerf view --ckpt style.ckpt --host 0.0.0.0 --port 8765"}},
      {"render", "stylise and render", "render a density or feature checkpoint: held-out views with PSNR/SSIM, or a camera path",
       {"stylerf render --ckpt density.ckpt --views test -o out", "stylerf render --ckpt features.ckpt --views path --frames 60 -o out"}},
      {"adain", "stylise and render", "2D AdaIN style transfer of one image (pretrained VGG-19 + decoder)",
       {"stylerf adain --content photo.png --style starry.jpg -o out.png"}},
      {"contact-sheet", "stylise and render", "grid of 2D AdaIN results: contents x styles",
       {"stylerf contact-sheet --contents a.png,b.png --styles s1.jpg,s2.jpg -o sheet.png"}},
      {"eval", "evaluate", "held-out styles against 2D AdaIN; consistency by the scene's geometry; the paper's table",
       {"stylerf eval style --ckpt style.ckpt --max-views 5", "stylerf eval consistency --help"}},
      {"eval style", "evaluate", "held-out styles: our stylised views vs 2D AdaIN, by the same VGG losses",
       {"stylerf eval style --ckpt style.ckpt --max-views 5 --json style.json",
        "stylerf eval style --ckpt style.ckpt --styles more_styles --images side_by_side"}},
      {"eval consistency", "evaluate", "one method's short- and long-range consistency on a path (RMSE, LPIPS)",
       {"stylerf eval consistency --ckpt style.ckpt --method stylerf --style starry.jpg --json stylerf.json",
        "stylerf eval consistency --ckpt density.ckpt --method adain --style starry.jpg --json adain.json"}},
      {"eval table", "evaluate", "the paper's Table 1 over scenes and styles: Markdown, JSON, video, plot",
       {"stylerf eval table --scene-ckpts density.ckpt,style.ckpt -o table"}},
      {"lpips", "evaluate", "LPIPS distance between two images (v0.1, --net vgg|alex; --mask for a masked LPIPS)",
       {"stylerf lpips a.png b.png", "stylerf lpips a.png b.png --net vgg --mask mask.png"}},
      {"demo-images", "tools", "make a content and a style image procedurally (for the demo)",
       {"stylerf demo-images -o demo --num-styles 32"}},
      {"devices", "tools", "list OpenCL devices and the one stylerf would use",
       {"stylerf devices", "stylerf devices --device gpu"}},
      {"tune", "tools", "tune GEMM for this device (CLBlast tuners + own kernel) into a tuning file",
       {"stylerf tune --quick", "stylerf tune --from-dir tuner_results -o tuning.json"}},
      {"bench", "tools", "benchmarks: gemm, conv, ops, field, density, targets, patch, dst, render, decoder-step",
       {"stylerf bench gemm --quick", "stylerf bench patch --stage 3 --profile paper --size 256 --json patch.json"}},
  };
  return index;
}

const CommandInfo* find_command_info(const std::string& name) {
  for (const auto& c : command_index())
    if (c.name == name) return &c;
  return nullptr;
}

std::vector<const CommandInfo*> subcommands_of(const std::string& parent) {
  std::vector<const CommandInfo*> subs;
  for (const auto& c : command_index())
    if (c.name.size() > parent.size() + 1 && c.name.compare(0, parent.size() + 1, parent + " ") == 0) subs.push_back(&c);
  return subs;
}

}  // namespace stylerf::cli
