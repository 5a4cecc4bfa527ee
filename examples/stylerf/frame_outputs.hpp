// What the rendering commands write: numbered frame names, PNGs from interleaved RGB, and an mp4 of a
// numbered PNG sequence through ffmpeg when it is on PATH (the library's writer, lib/io/video.hpp).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "lib/io/image.hpp"
#include "lib/io/video.hpp"

namespace stylerf::cli {

// dir / (stem + i zero-padded to `digits` + ext)
std::string numbered(const std::filesystem::path& dir, const std::string& stem, int i, int digits,
                     const std::string& ext);
// Interleaved [h][w][3] in [0, 1] -> a planar image.
io::Image interleaved_image(const std::vector<float>& rgb, int w, int h);
// Grey [h][w] in [0, 1] -> an RGB image.
io::Image grey_image(const std::vector<float>& v, int w, int h);
// pattern e.g. "frame_%04d.png" inside dir -> dir/name. Returns false (and says how to make it) without
// ffmpeg; throws when ffmpeg fails.
using io::write_video;

}  // namespace stylerf::cli
