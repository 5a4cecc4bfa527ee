// 2D AdaIN style transfer (Huang & Belongie 2017), the image-space baseline of StyleRF and the check that
// the pretrained encoder/decoder pair works: encode content and style to relu4_1, move the content
// features' channel means/stds to the style's, blend with the content by alpha, decode.
#pragma once
#include <string>

#include "lib/io/image.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::style {

struct AdainModel {
  nn::VggEncoder encoder;
  nn::ConvStack decoder;  // AdaIN's pretrained decoder (nn::load_adain_decoder)
  // From the weights folder (nn::weights_dir()); errors name the missing file and the set-up command.
  static AdainModel load_default();
};

// content [1,3,H,W], style [1,3,h,w], RGB in [0,1], sides multiples of 8. Returns the decoded image
// [1,3,H,W], not clamped. alpha = 1: full stylisation; alpha = 0: dec(enc(content)).
host::Tensor adain_stylize(AdainModel& model, const host::Tensor& content, const host::Tensor& style, float alpha);

// Sides AdaIN accepts: relu4_1 is at 1/8 and its reflect padding needs 2 px there; 4096 bounds the memory
// (a 4096x4096 relu1_1 map is 4 GB).
constexpr int kAdainMinSide = 16, kAdainMaxSide = 4096;
// Loads an image and resizes it so its longer side is `size` (in [16, 4096]), both sides multiples of 8;
// an image whose shorter side would fall below 16 is an error naming the file, before any compute.
io::Image load_image_for_adain(const std::string& path, int size);

// Files in, PNG out: the `stylerf adain` command's work. The output is clamped to [0,1].
io::Image adain_files(AdainModel& model, const std::string& content_path, const std::string& style_path,
                      float alpha, int size);

}  // namespace stylerf::style
