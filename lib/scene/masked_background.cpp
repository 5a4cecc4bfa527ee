#include "lib/scene/masked_background.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace stylerf::scene {

namespace {

// Appends the border ring of one image ([h][w][3]) to out (interleaved rgb).
void append_ring(const View& v, std::vector<float>& out) {
  const int w = v.camera.width, h = v.camera.height;
  if (w <= 0 || h <= 0 || v.rgb.size() != size_t(w) * h * 3) return;
  const int b = std::max(1, std::min(w, h) / 50);
  for (int y = 0; y < h; ++y) {
    const bool edge_row = y < b || y >= h - b;
    for (int x = 0; x < w; ++x) {
      if (!edge_row && x >= b && x < w - b) {
        x = w - b - 1;  // skip the interior of this row
        continue;
      }
      const float* p = &v.rgb[(size_t(y) * w + x) * 3];
      out.insert(out.end(), p, p + 3);
    }
  }
}

}  // namespace

BorderColour border_colour(const std::vector<View>& views, float tolerance) {
  std::vector<float> ring;
  for (const View& v : views) append_ring(v, ring);
  BorderColour r;
  r.pixels = long(ring.size() / 3);
  if (r.pixels == 0) return r;
  std::vector<float> channel(size_t(r.pixels));
  for (int c = 0; c < 3; ++c) {
    for (long i = 0; i < r.pixels; ++i) channel[size_t(i)] = ring[size_t(i) * 3 + c];
    auto mid = channel.begin() + r.pixels / 2;
    std::nth_element(channel.begin(), mid, channel.end());
    r.rgb[size_t(c)] = *mid;
  }
  long same = 0;
  for (long i = 0; i < r.pixels; ++i) {
    float d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::fabs(ring[size_t(i) * 3 + c] - r.rgb[size_t(c)]));
    same += d <= tolerance;
  }
  r.share = double(same) / double(r.pixels);
  return r;
}

void detect_plain_background(Scene& s) {
  const bool object = s.format.size() > 7 && s.format.compare(s.format.size() - 7, 7, "-object") == 0;
  if (!object || s.effects.background || s.train.empty() || s.train[0].rgb.empty()) return;
  const BorderColour b = border_colour(s.train);
  char text[200];
  std::snprintf(text, sizeof text, "%.0f%% of the training views' border pixels are (%.3g, %.3g, %.3g)", 100.0 * b.share,
                b.rgb[0], b.rgb[1], b.rgb[2]);
  if (b.share < kUniformBorderShare) {
    if (!(s.shell_radius > 0) || s.effects.ndc) return;
    s.effects.background_shell = true;
    char radius[64];
    std::snprintf(radius, sizeof radius, "%.3g", s.shell_radius);
    s.notes.push_back(std::string("background shell on: only ") + text +
                      " (real surroundings; rays leaving the box see a map on a sphere of radius " + radius +
                      ", the median reach of the far bounds)");
    return;
  }
  s.effects.background = true;
  s.effects.background_rgb = b.rgb;
  s.effects.background_reason = "plain backdrop";
  s.notes.push_back(std::string("background colour on: ") + text + " (a plain or masked backdrop; rays leaving the box see it)");
}

std::vector<uint8_t> backdrop_pixels(const Scene& s, const View& v) {
  const int w = v.camera.width, h = v.camera.height;
  const size_t n = size_t(w) * size_t(h);
  if (!s.effects.background || n == 0 || v.rgb.size() != 3 * n) return {};
  std::vector<uint8_t> mask(n, 0);
  if (!v.alpha.empty()) {
    if (v.alpha.size() != n) return {};
    for (size_t i = 0; i < n; ++i) mask[i] = v.alpha[i] < kBackdropAlpha;
    return mask;
  }
  const auto& bg = s.effects.background_rgb;
  auto plain = [&](size_t i) {
    float d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::fabs(v.rgb[3 * i + size_t(c)] - bg[size_t(c)]));
    return d <= kBorderTolerance;
  };
  std::vector<size_t> stack;
  auto visit = [&](int x, int y) {
    const size_t i = size_t(y) * size_t(w) + size_t(x);
    if (!mask[i] && plain(i)) mask[i] = 1, stack.push_back(i);
  };
  for (int x = 0; x < w; ++x) visit(x, 0), visit(x, h - 1);
  for (int y = 0; y < h; ++y) visit(0, y), visit(w - 1, y);
  while (!stack.empty()) {
    const size_t i = stack.back();
    stack.pop_back();
    const int x = int(i % size_t(w)), y = int(i / size_t(w));
    if (x > 0) visit(x - 1, y);
    if (x + 1 < w) visit(x + 1, y);
    if (y > 0) visit(x, y - 1);
    if (y + 1 < h) visit(x, y + 1);
  }
  return mask;
}

}  // namespace stylerf::scene
