#include "lib/eval/path_frames.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/model/opacity_head.hpp"
#include "lib/scene/camera_path.hpp"

namespace stylerf::eval {

using host::Error;

std::vector<scene::Camera> path_cameras(const scene::Scene& scene, int frames, int path_frames, int size) {
  if (frames < 1 || path_frames < frames)
    throw host::SettingError("frames", "must be in 1..path_frames (got " + std::to_string(frames) + " and " +
                std::to_string(path_frames) + ")");
  if (size < 0 || size > 4096) throw host::SettingError("size", "must be in [0, 4096] (0: the scene's)");
  const auto path = scene::default_path(scene, path_frames);
  std::vector<scene::Camera> out(path.begin(), path.begin() + frames);
  for (auto& c : out) c = c.with_longer_side(size);
  return out;
}

std::vector<FrameGeometry> render_path_geometry(const model::Geometry& g, const scene::Scene& scene,
                                                const std::vector<scene::Camera>& cams, int chunk) {
  std::vector<FrameGeometry> out;
  for (const auto& cam : cams) {
    auto v = model::render_geometry(g, scene, cam, chunk);
    out.push_back({cam, std::move(v.depth), std::move(v.acc)});
  }
  return out;
}

io::Image planar_image(const std::vector<float>& interleaved, int width, int height) {
  const size_t plane = size_t(width) * height;
  if (interleaved.size() != plane * 3)
    throw Error("planar_image: " + std::to_string(interleaved.size()) + " values for " + std::to_string(width) + "x" +
                std::to_string(height) + " RGB");
  io::Image img;
  img.width = width;
  img.height = height;
  img.data.resize(plane * 3);
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = interleaved[i * 3 + c];
  return img;
}

std::vector<io::Image> rgb_frames(const model::DensityModel& m, const scene::Scene& scene,
                                  const std::vector<scene::Camera>& cams, int chunk,
                                  std::vector<FrameGeometry>* geometry) {
  std::vector<io::Image> out;
  if (geometry) geometry->clear();
  for (const auto& cam : cams) {
    auto v = model::render_view(m, scene, cam, chunk);
    io::Image img = planar_image(v.value, v.width, v.height);
    for (float& x : img.data) x = std::clamp(x, 0.0f, 1.0f);
    out.push_back(std::move(img));
    if (geometry) geometry->push_back({cam, std::move(v.depth), std::move(v.acc)});
  }
  return out;
}

io::Image load_style_for_eval(const std::string& path) {
  return io::resize(io::load_image(path), kStyleSide, kStyleSide);
}

std::vector<io::Image> adain_frames(style::AdainModel& adain, const std::vector<io::Image>& content,
                                    const io::Image& style_image) {
  const host::Tensor style = io::to_tensor(style_image);
  std::vector<io::Image> out;
  for (const auto& frame : content) {
    const auto [w, h] = io::fit_size(frame.width, frame.height, std::max(frame.width, frame.height), 8);
    if (std::min(w, h) < style::kAdainMinSide)
      throw Error("adain frames: a " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                  " frame is too small for AdaIN (shorter side >= " + std::to_string(style::kAdainMinSide) + ")");
    const io::Image sized = (w == frame.width && h == frame.height) ? frame : io::resize(frame, w, h);
    io::Image styled = io::from_tensor(style::adain_stylize(adain, io::to_tensor(sized), style, 1.0f));
    if (w != frame.width || h != frame.height) styled = io::resize(styled, frame.width, frame.height);
    for (float& x : styled.data) x = std::clamp(x, 0.0f, 1.0f);
    out.push_back(std::move(styled));
  }
  return out;
}

std::vector<model::StyleModel::CameraContent> content_frames(const model::StyleModel& m, const scene::Scene& scene,
                                                              const std::vector<scene::Camera>& cams, int chunk,
                                                              int supersample, float refine_contrast) {
  std::vector<model::StyleModel::CameraContent> out;
  out.reserve(cams.size());
  for (const auto& cam : cams)
    out.push_back(m.render_camera_content(scene, cam, chunk, nullptr, supersample, refine_contrast));
  return out;
}

std::vector<io::Image> stylerf_frames(const model::StyleModel& m,
                                      const std::vector<model::StyleModel::CameraContent>& contents,
                                      const std::vector<scene::Camera>& cams, const style::StyleCode& code,
                                      bool over_background) {
  if (contents.size() != cams.size())
    throw Error("stylerf frames: " + std::to_string(contents.size()) + " contents for " +
                std::to_string(cams.size()) + " cameras");
  std::vector<io::Image> out;
  for (size_t i = 0; i < cams.size(); ++i) {
    const auto& cam = cams[i];
    auto rgb = m.stylize_camera(contents[i], code, cam.width, cam.height);
    if (over_background) m.over_background(rgb, contents[i], cam.width, cam.height);
    out.push_back(planar_image(rgb, cam.width, cam.height));
  }
  return out;
}

std::vector<io::Image> stylerf_frames(const model::StyleModel& m, const scene::Scene& scene,
                                      const std::vector<scene::Camera>& cams, const style::StyleCode& code,
                                      bool over_background, int chunk, int supersample,
                                      float refine_contrast) {
  std::vector<io::Image> out;
  for (const auto& cam : cams) {
    const std::vector<model::StyleModel::CameraContent> one{
        m.render_camera_content(scene, cam, chunk, nullptr, supersample, refine_contrast)};
    out.push_back(stylerf_frames(m, one, {cam}, code, over_background).front());
  }
  return out;
}

}  // namespace stylerf::eval
