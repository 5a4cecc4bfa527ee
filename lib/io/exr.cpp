#include "lib/io/exr.hpp"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>

#include <filesystem>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::io {

using host::Error;

namespace {
const char* const kRgb[3] = {"R", "G", "B"};
const char* channel_name(int channels, int c) { return channels == 1 ? "Y" : kRgb[c]; }
}  // namespace

void write_exr(const std::string& path, const std::vector<float>& data, int width, int height, int channels) {
  if (channels != 1 && channels != 3) throw Error("write_exr " + path + ": channels must be 1 or 3");
  if (width <= 0 || height <= 0 || data.size() != size_t(channels) * width * height)
    throw Error("write_exr " + path + ": data size does not match " + std::to_string(channels) + "x" +
                std::to_string(height) + "x" + std::to_string(width));
  host::write_atomic_with(path, [&](const std::string& tmp) {
    try {
      Imf::Header header(width, height);
      header.compression() = Imf::ZIP_COMPRESSION;
      Imf::FrameBuffer fb;
      for (int c = 0; c < channels; ++c) {
        header.channels().insert(channel_name(channels, c), Imf::Channel(Imf::FLOAT));
        char* base = reinterpret_cast<char*>(const_cast<float*>(data.data() + size_t(c) * width * height));
        fb.insert(channel_name(channels, c), Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * width));
      }
      Imf::OutputFile file(tmp.c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(height);
    } catch (const std::exception& e) {
      throw Error("cannot write EXR " + path + ": " + e.what());
    }
  });
}

ExrImage read_exr(const std::string& path) {
  if (!std::filesystem::exists(path)) throw Error("EXR file " + path + " does not exist");
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    ExrImage img;
    img.width = dw.max.x - dw.min.x + 1;
    img.height = dw.max.y - dw.min.y + 1;
    img.channels = file.header().channels().findChannel("Y") ? 1 : 3;
    img.data.assign(size_t(img.channels) * img.width * img.height, 0.0f);
    Imf::FrameBuffer fb;
    for (int c = 0; c < img.channels; ++c) {
      // The slice base is addressed by absolute pixel coordinates, so shift it by the window origin.
      char* base = reinterpret_cast<char*>(img.data.data() + size_t(c) * img.width * img.height) -
                   (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * img.width) * ptrdiff_t(sizeof(float));
      fb.insert(channel_name(img.channels, c),
                Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * img.width));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return img;
  } catch (const std::exception& e) {
    throw Error("cannot read EXR " + path + ": " + e.what());
  }
}

}  // namespace stylerf::io
