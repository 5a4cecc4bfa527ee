// What the rendering commands write: numbered frame names, PNGs from interleaved RGB, and an mp4 of a
// numbered PNG sequence through ffmpeg when it is on PATH (written atomically).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "lib/io/image.hpp"

namespace stylerf::cli {

// dir / (stem + i zero-padded to `digits` + ext)
std::string numbered(const std::filesystem::path& dir, const std::string& stem, int i, int digits,
                     const std::string& ext);
// Interleaved [h][w][3] in [0, 1] -> a planar image.
io::Image interleaved_image(const std::vector<float>& rgb, int w, int h);
// Grey [h][w] in [0, 1] -> an RGB image.
io::Image grey_image(const std::vector<float>& v, int w, int h);
bool have_ffmpeg();
// pattern e.g. "frame_%04d.png" inside dir -> dir/name. Returns false (and says how to make it) without
// ffmpeg; throws when ffmpeg fails.
bool write_video(const std::string& dir, const std::string& pattern, const std::string& name, int fps,
                 std::ostream& log);

}  // namespace stylerf::cli
