// The styles a viewer offers: images from files (a checkpoint's held-out styles, a folder) and images
// uploaded by its clients, each under an id the server gives (clients never name files). Each has a
// thumbnail (PNG bytes, made when added) and its style code, encoded on first use (zero-shot: once).
// Thread-safe: listing and adding from any thread; code() runs the style branch on the device and must be
// called from the one thread that uses the device.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "lib/style/dst.hpp"
#include "lib/style/style_encoder.hpp"

namespace stylerf::viewer {

constexpr int kThumbSide = 96;  // thumbnails' longer side in pixels

struct StyleEntry {
  std::string id, name, source;  // source: "holdout", "folder" or "upload"
  std::string path;              // the image file (uploads: a copy in the library's folder)
  std::string thumb_png;
};

class StyleLibrary {
 public:
  // upload_dir: where uploaded images are kept (created; the caller removes it).
  explicit StyleLibrary(std::string upload_dir);

  // An image file as a style: its id. Throws host::Error naming the file when it is not a readable image.
  std::string add_file(const std::string& path, const std::string& name, const std::string& source);
  // Uploaded bytes as a style: written into the upload folder under a name of the library's, checked to be
  // an image (PNG, JPEG, BMP...; throws host::Error saying what it is not, and keeps nothing), then added.
  std::string add_upload(const std::string& bytes, const std::string& name);

  std::vector<StyleEntry> list() const;
  std::optional<StyleEntry> find(const std::string& id) const;
  // The id's style code (encoded the first time). Throws host::Error for an unknown id.
  style::StyleCode code(const std::string& id, style::StyleEncoder& encoder);

 private:
  mutable std::mutex mu_;
  std::string upload_dir_;
  std::vector<StyleEntry> entries_;
  std::map<std::string, style::StyleCode> codes_;
  int64_t uploads_ = 0;
};

// A display name from a client: printable ASCII, at most 64 characters, "style" when nothing is left.
std::string clean_style_name(const std::string& name);

}  // namespace stylerf::viewer
