// Style images as the style branch reads them: any image io::load_image decodes (PNG 8/16-bit, JPEG, BMP,
// grey or with alpha; alpha is dropped), resized to size x size, then a crop x crop window (training: at
// a random corner; inference: crop == size, the whole image). [1, 3, crop, crop] RGB in [0, 1].
// Errors name the file: unreadable or unsupported (e.g. a CMYK JPEG or WebP), or values that are not finite.
#pragma once
#include <random>
#include <ostream>
#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/io/image.hpp"

namespace stylerf::style {

host::Tensor load_style_image(const std::string& path, int size, int crop, std::mt19937_64* rng);

// The two halves of load_style_image, for callers that crop one image many times (style training draws
// each of ~100 images tens of times, and its ~1-megapixel JPEGs need not be decoded and resized again):
// the decoded image resized to size x size, checked finite; and a crop x crop window of it (at a
// random corner with `rng`, else centred). `path` only names the image in errors.
io::Image load_style_source(const std::string& path, int size);
host::Tensor crop_style_image(const io::Image& source, int crop, std::mt19937_64* rng, const std::string& path);

// The style images of a folder in name order: files named .jpg/.jpeg/.png (any case) that decode. Files
// that cannot be decoded (a WebP saved as .jpg, a text file renamed) are left out, each named with its
// reason on `log`: one bad file must not stop a run of hours at the step that draws it. Throws when `dir`
// is not a folder.
std::vector<std::string> style_images_in(const std::string& dir, std::ostream* log);

}  // namespace stylerf::style
