// The one scene description every stage works from: cameras with their images, the ray-sampling range,
// the bounding box, and the effects the scene calls for. Loaders (Blender, LLFF forward-facing, LLFF
// object-centric) fill it; `load_scene` picks the loader from the files in the directory.
//
// Conventions
// - World and camera frames follow NeRF/OpenGL: camera x right, y up, looking down -z. c2w maps camera
//   coordinates to world: world = R * cam + t with R = c2w[:][0..2], t = c2w[:][3].
// - Pixel (x, y) has its centre at (x + 0.5, y + 0.5); the camera-space direction of a pixel centre is
//   ((x + 0.5 - cx) / fx, -(y + 0.5 - cy) / fy, -1). Images are row-major, row 0 at the top.
// - Images are stored interleaved, rgb[(y * width + x) * 3 + c], values in [0,1], already composited over
//   the background when the file had alpha; alpha (when the file had it) is [height * width].
// - near/far are the ray-parameter range in the scene's ray space: world distance along normalised rays,
//   or the NDC parameter in [0, 1] when effects.ndc is on (see rays.hpp).
#pragma once
#include <array>
#include <iosfwd>
#include <string>
#include <vector>

namespace stylerf::scene {

struct Camera {
  float c2w[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
  float fx = 1, fy = 1, cx = 0, cy = 0;
  int width = 0, height = 0;

  std::array<float, 3> position() const { return {c2w[0][3], c2w[1][3], c2w[2][3]}; }
  // Unit viewing direction (the camera's -z axis in world space).
  std::array<float, 3> forward() const { return {-c2w[0][2], -c2w[1][2], -c2w[2][2]}; }
  // Same camera with the image scaled to width x height (intrinsics scaled per axis).
  Camera resized(int new_width, int new_height) const;
  // Same camera with its longer side `size` pixels and the aspect kept (size <= 0: unchanged).
  Camera with_longer_side(int size) const;
  // Pixel coordinates (continuous, pixel centres at +0.5) of a world point; false if it is behind.
  bool project(const std::array<float, 3>& world, float& px, float& py) const;
};

struct SceneEffects {
  bool ndc = false;              // rays in normalised device coordinates (forward-facing LLFF)
  bool background = false;       // rays leaving the content see background_rgb (see background_reason)
  std::array<float, 3> background_rgb{1, 1, 1};
  std::string background_reason = "images have alpha";  // or a plain backdrop read off the borders
  // Object captures with real surroundings (a room around the object): rays leaving the box see a map on a
  // sphere of radius shell_radius about the centre (lib/render/background_shell.hpp). Off with a background
  // colour, and for forward-facing captures, whose NDC rays reach the far plane inside the box.
  bool background_shell = false;
  bool view_dependence = false;  // appearance may depend on the view direction (only when asked for)
};

struct View {
  Camera camera;
  std::string image_path;
  std::vector<float> rgb;    // [height][width][3], see conventions above
  std::vector<float> alpha;  // [height][width] or empty
};

struct Scene {
  std::string name, root;
  std::string format;  // "blender", "llff-forward", "llff-object"
  std::vector<View> train, test;
  float near = 0, far = 1;  // ray-parameter range (NDC: 0..1)
  float ndc_near = 1;       // world-space plane z = -ndc_near that NDC rays start on (NDC scenes only)
  float depth_near = 0, depth_far = 0;  // world-space depth bounds of the content (spiral path focus)
  float shell_radius = 0;  // object captures: the sphere the surroundings are painted on (0: not measured)
  float aabb[2][3] = {{-1.5f, -1.5f, -1.5f}, {1.5f, 1.5f, 1.5f}};  // in the ray space (NDC box when ndc)
  SceneEffects effects;
  std::vector<std::string> notes;  // decisions taken while loading (printed by describe())

  int width() const { return train.empty() ? 0 : train[0].camera.width; }
  int height() const { return train.empty() ? 0 : train[0].camera.height; }
  // Multi-line summary: format, counts, resolution, intrinsics, near/far, box, effects on, decisions.
  std::string describe() const;
};

enum class Switch { automatic, on, off };
// "auto" | "on" | "off" -> Switch; anything else throws an Error naming the flag and the value.
Switch parse_switch(const std::string& value, const std::string& flag);

struct LoadOptions {
  int downsample = 1;                 // Blender: resize by 1/N; LLFF: images_N (or resize images/)
  Switch ndc = Switch::automatic;     // LLFF: forward-facing -> NDC unless overridden
  bool view_dependence = false;       // switched on only when asked for
  bool load_images = true;            // false: cameras only (image sizes still read from the headers)
  std::ostream* log = nullptr;        // where describe() is printed after loading (nullptr: silent)
};

// Picks the format from the files in `dir` (transforms_train.json -> Blender, poses_bounds.npy -> LLFF),
// loads, validates (counts, finite poses, readable images of one size) and prints describe() to opts.log.
Scene load_scene(const std::string& dir, const LoadOptions& opts = {});

// The downsample factor a scene trains at when none is given: the resolutions the paper reports, Blender
// at its own 800x800 (1) and LLFF at 1/4 (1008x756 from 4032x3024 captures: 4). LLFF captures of smaller
// images take the smallest power of two that brings the longer side of images/ to at most
// kLlffLongestSide (544x960: 1; 1140x855: 2); without images/ 4. COLMAP and nerfstudio folders at 1
// (`stylerf import` already bounds their image size). `requested` > 0 is returned as is.
constexpr int kLlffLongestSide = 1024;
int resolve_downsample(const std::string& dir, int requested);

// Throws host::Error naming `what` if any entry of the 3x4 pose is NaN or infinite.
// Throws naming `what` unless the camera-to-world matrix is finite and rigid (orthonormal rotation, det +1).
void check_pose(const double c2w[3][4], const std::string& what);
void check_pose_finite(const float c2w[3][4], const std::string& what);  // the same, float

}  // namespace stylerf::scene
