// The per-view yardstick of `stylerf stylize`: content loss (relu4_1) and style loss (relu1_1..relu4_1
// mean/std, x20), the training weights (lib/train/style_losses.hpp), of each stylised frame. The content
// reference is the true image on test views and stage 2's unstylised render on path views; the style
// reference is the style image at 256 x 256. Test views also get the same losses for 2D AdaIN applied to
// the true view (alpha 1), by the same VGG and the same mask. Scenes with a background are masked by the
// rendered opacity. Images are cut to multiples of 8. Mixed and composed frames get no style loss (no one
// style to compare with): only their content loss.
#pragma once
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lib/model/style_model.hpp"
#include "lib/style/adain.hpp"
#include "lib/train/style_losses.hpp"

namespace stylerf::cli {

class ViewLosses {
 public:
  ViewLosses(const model::StyleModel& m, nn::VggEncoder& vgg, bool adain_baseline);
  void add_style(const std::string& path);  // one per output set; "" = no style loss
  // The view's references (truth: the test view, or null for a path camera), then one call per output set.
  void begin_view(const scene::Scene& scene, const scene::View* truth, const scene::Camera& cam,
                  const model::StyleModel::CameraContent& cc);
  nlohmann::json measure(const std::vector<float>& rgb, int cam_w, size_t set);
  nlohmann::json means() const;
  std::string summary() const;
  // Several ranks, each with its share of the views: every rank's sums added, so means() covers all views.
  void merge_ranks();

 private:
  struct Style {
    std::string path;
    host::Tensor image;
    train::StyleTargets targets;  // each tap's channel statistics, reduced once for every frame
  };
  struct Sums {
    double ours_content = 0, ours_style = 0, adain_content = 0, adain_style = 0;
    int views = 0, adain_views = 0;
  };
  const model::StyleModel& m_;
  nn::VggEncoder& vgg_;
  std::unique_ptr<style::AdainModel> adain_;
  std::vector<Style> styles_;
  std::vector<Sums> sums_;
  // the current view
  int He_ = 0, We_ = 0;
  host::Tensor truth_, content41_;
  train::OpacityMask mask_;
  bool masked_ = false, skip_ = false;
};

}  // namespace stylerf::cli
