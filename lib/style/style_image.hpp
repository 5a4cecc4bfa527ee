// Style images as the style branch reads them: any image io::load_image decodes (PNG 8/16-bit, JPEG, BMP,
// grey or with alpha; alpha is dropped), resized to size x size, then a crop x crop window (training: at
// a random corner; inference: crop == size, the whole image). [1, 3, crop, crop] RGB in [0, 1].
// Errors name the file: unreadable or unsupported (e.g. a CMYK JPEG or WebP), or values that are not finite.
#pragma once
#include <random>
#include <string>

#include "host/tensor.hpp"

namespace stylerf::style {

host::Tensor load_style_image(const std::string& path, int size, int crop, std::mt19937_64* rng);

}  // namespace stylerf::style
