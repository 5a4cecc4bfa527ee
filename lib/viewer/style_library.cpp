#include "lib/viewer/style_library.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "host/error.hpp"
#include "lib/io/image.hpp"

namespace stylerf::viewer {

namespace fs = std::filesystem;

namespace {

std::string thumbnail_png(const std::string& path) {
  const io::Image img = io::load_image(path);
  const double s = double(kThumbSide) / std::max(img.width, img.height);
  const int w = std::max(1, int(img.width * s + 0.5)), h = std::max(1, int(img.height * s + 0.5));
  return io::encode_png(io::resize(img, w, h));
}

}  // namespace

std::string clean_style_name(const std::string& name) {
  std::string out;
  for (char c : name)
    if (c >= 0x20 && c < 0x7f && out.size() < 64) out += c;
  return out.empty() ? "style" : out;
}

StyleLibrary::StyleLibrary(std::string upload_dir) : upload_dir_(std::move(upload_dir)) {
  fs::create_directories(upload_dir_);
}

std::string StyleLibrary::add_file(const std::string& path, const std::string& name, const std::string& source) {
  const std::string why = io::image_unreadable_reason(path);
  if (!why.empty()) throw host::Error("style image " + path + ": " + why);
  StyleEntry e{"", clean_style_name(name), source, path, thumbnail_png(path)};
  std::lock_guard<std::mutex> lock(mu_);
  e.id = "s" + std::to_string(entries_.size());
  entries_.push_back(e);
  return e.id;
}

std::string StyleLibrary::add_upload(const std::string& bytes, const std::string& name) {
  std::string path;
  {
    std::lock_guard<std::mutex> lock(mu_);
    path = (fs::path(upload_dir_) / ("upload_" + std::to_string(uploads_++))).string();
  }
  {
    std::ofstream f(path, std::ios::binary);
    f.write(bytes.data(), std::streamsize(bytes.size()));
    if (!f) throw host::Error("cannot keep the uploaded image in " + upload_dir_);
  }
  // Refusals quote no path of the server's: a client never learns where its upload went.
  auto refuse = [&](std::string why) {
    std::error_code ec;
    fs::remove(path, ec);
    for (size_t at = why.find(path); at != std::string::npos; at = why.find(path)) why.replace(at, path.size(), "it");
    throw host::Error("the upload '" + clean_style_name(name) + "' is not an image stylerf can read: " + why);
  };
  const std::string why = bytes.empty() ? "the upload is empty" : io::image_unreadable_reason(path);
  if (!why.empty()) refuse(why);
  try {
    return add_file(path, name, "upload");
  } catch (const host::Error& e) {  // decodes no further than its header (too large, truncated)
    refuse(e.what());
  }
  return "";
}

std::vector<StyleEntry> StyleLibrary::list() const {
  std::lock_guard<std::mutex> lock(mu_);
  return entries_;
}

std::optional<StyleEntry> StyleLibrary::find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  for (const auto& e : entries_)
    if (e.id == id) return e;
  return std::nullopt;
}

style::StyleCode StyleLibrary::code(const std::string& id, style::StyleEncoder& encoder) {
  std::string path;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = codes_.find(id); it != codes_.end()) return it->second;
  }
  const auto entry = find(id);
  if (!entry) throw host::Error("no style with id '" + id + "'");
  const style::StyleCode c = encoder.encode(entry->path).code;
  std::lock_guard<std::mutex> lock(mu_);
  codes_[id] = c;
  return c;
}

}  // namespace stylerf::viewer
