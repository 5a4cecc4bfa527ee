#include "lib/style/adain.hpp"

#include <algorithm>

#include "host/error.hpp"

namespace stylerf::style {

using host::Error;
using host::Tensor;

AdainModel AdainModel::load_default() {
  AdainModel m;
  m.encoder = nn::VggEncoder::load_default();
  m.decoder = nn::load_adain_decoder();  // refuses a file of another architecture, naming it
  m.decoder.freeze();                     // pretrained and never trained: its filter transforms are kept
  return m;
}

Tensor adain_stylize(AdainModel& model, const Tensor& content, const Tensor& style, float alpha) {
  if (!(alpha >= 0.0f && alpha <= 1.0f)) throw Error("adain: alpha must be in [0, 1]");
  // Inference only: nothing is kept for backward.
  Tensor fc = model.encoder.forward(content, 4, false)[3];
  Tensor fs = model.encoder.forward(style, 4, false)[3];
  Tensor t = nn::adain_forward(fc, fs);
  if (alpha < 1.0f) nn::axpby(1.0f - alpha, fc, alpha, t);  // t = alpha * t + (1 - alpha) * fc
  return model.decoder.forward(t);
}

io::Image load_image_for_adain(const std::string& path, int size) {
  if (size < kAdainMinSide || size > kAdainMaxSide)
    throw host::SettingError("size", "must be in [" + std::to_string(kAdainMinSide) + ", " + std::to_string(kAdainMaxSide) +
                "] (got " + std::to_string(size) + ")");
  // Transparent pixels (Blender renders) become white, as the scenes are shown.
  const std::array<float, 3> white{1.0f, 1.0f, 1.0f};
  io::Image img = io::load_image(path, &white);
  auto [w, h] = io::fit_size(img.width, img.height, size, 8);
  if (std::min(w, h) < kAdainMinSide)
    throw Error("adain: " + path + " is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                ": at --size " + std::to_string(size) + " its shorter side would be " + std::to_string(std::min(w, h)) +
                " px, and AdaIN needs " + std::to_string(kAdainMinSide) +
                " (VGG pools three times; reflect padding then needs 2 px)");
  return io::resize(img, w, h);
}

io::Image adain_files(AdainModel& model, const std::string& content_path, const std::string& style_path, float alpha,
                      int size) {
  io::Image c = load_image_for_adain(content_path, size);
  io::Image s = load_image_for_adain(style_path, size);
  io::Image out = io::from_tensor(adain_stylize(model, io::to_tensor(c), io::to_tensor(s), alpha));
  for (float& v : out.data) v = std::clamp(v, 0.0f, 1.0f);
  return out;
}

}  // namespace stylerf::style
