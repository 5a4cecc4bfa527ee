// OpenEXR output for float data (depth maps, feature visualisations): one channel ("Y") or three
// ("R", "G", "B"), 32-bit float, ZIP compression, written atomically. A reader is here for tests and tools.
#pragma once
#include <string>
#include <vector>

namespace stylerf::io {

// data: channels planes of height*width floats ([C][H][W]); channels is 1 or 3.
void write_exr(const std::string& path, const std::vector<float>& data, int width, int height, int channels);

struct ExrImage {
  int width = 0, height = 0, channels = 0;
  std::vector<float> data;  // [C][H][W]
};
// Reads a file written by write_exr (channel Y, or R, G, B). Errors name the file.
ExrImage read_exr(const std::string& path);

}  // namespace stylerf::io
