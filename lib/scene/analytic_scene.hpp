// A tiny CPU ray tracer of analytic shapes (spheres, axis-aligned boxes, vertical capped cylinders,
// a horizontal disc floor) with solid textures (checker, stripes) and Lambert shading from one fixed
// light. Colours depend only on the surface point, never on the view, so a radiance field without view
// dependence can reproduce them exactly; depth is exact. Used by `stylerf make-scene` (objects floating
// in empty space, transparent background) and by the demo content image (objects on a checker floor).
// World frame: z up, as Blender scenes.
#pragma once
#include <array>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

using Float3 = std::array<float, 3>;

// noise: a solid value noise of four octaves between colours a and b, with a third colour c at the top of
// its range: blobs at every scale, which feature matchers (COLMAP's SIFT) find in any view.
enum class Pattern { solid, checker, stripes, noise };

struct Material {
  Float3 a{0.8f, 0.8f, 0.8f}, b{0.2f, 0.2f, 0.2f};  // the two colours of the pattern (solid: a)
  Pattern pattern = Pattern::solid;
  float frequency = 4.0f;  // cells per unit length, in the shape's local frame (origin at `p`)
  Float3 c{0.95f, 0.95f, 0.9f};  // noise only: its brightest blobs
};

struct Shape {
  enum class Kind { sphere, box, cylinder, disc } kind = Kind::sphere;
  Float3 p{0, 0, 0};  // sphere: centre; box: min corner; cylinder: centre of the bottom cap; disc: centre
  Float3 q{0, 0, 0};  // box: max corner
  float radius = 1, height = 1;  // sphere, cylinder, disc: radius; cylinder: height along +z
  Material material;
};

struct SurfaceHit {
  bool hit = false;
  float t = 0;  // distance along the (unit) direction
  Float3 point{}, normal{}, albedo{};
};

struct AnalyticScene {
  std::vector<Shape> shapes;
  Float3 light{0.431934f, 0.259161f, 0.863868f};  // unit vector towards the light: (0.5, 0.3, 1) normalised
  float ambient = 0.3f;
  bool shadows = true;

  // Nearest surface with t > 1e-4 along o + t d (d unit length).
  SurfaceHit trace(const Float3& o, const Float3& d) const;
  // Lambert: albedo * (ambient + (1 - ambient) * max(0, n.l)), the direct term removed in shadow.
  Float3 shade(const SurfaceHit& h) const;

  // make-scene's content: a checker sphere, a checker box, a striped cylinder and a plain sphere, all
  // inside [-1.2, 1.2]^3 (so inside the Blender box [-1.5, 1.5]^3), no floor.
  static AnalyticScene objects();
  // The demo content image: plain shapes standing on a checker disc floor (z = 0, radius 6).
  static AnalyticScene on_floor();
  // make-scene --textured: noise-textured shapes on a noise-textured disc floor (z = -0.9, radius 2.4), so
  // that structure from motion registers every view (the COLMAP import's end-to-end test).
  static AnalyticScene textured();
};

struct AnalyticView {
  std::vector<float> rgb;    // [H][W][3], straight (not premultiplied) colour of the covered part
  std::vector<float> alpha;  // [H][W], fraction of the pixel covered by surfaces
  std::vector<float> depth;  // [H][W], distance along the pixel-centre ray (0 where it misses)
};

// Renders a camera with `ss` x `ss` supersamples per pixel for colour and alpha; depth comes from the
// pixel-centre ray (the ray rays.hpp generates), so a test can check rays against it exactly.
AnalyticView render_analytic(const AnalyticScene& scene, const Camera& cam, int ss = 2);

}  // namespace stylerf::scene
