// Camera paths in nerfstudio's camera_path.json format, the file its viewer exports and `ns-render` reads,
// so that a path designed there renders here and a path exported here opens there.
//
// The format (the keys this reads and writes):
//   {"camera_type": "perspective", "render_width": W, "render_height": H, "fps": 30, "seconds": N / fps,
//    "camera_path": [{"camera_to_world": [16 numbers, a row-major 4x4], "fov": vertical field of view in
//                     degrees, "aspect": W / H}, ...]}
// One entry per frame (the viewer writes the interpolated frames there, its keyframes under other keys, which
// are ignored). The camera axes are OpenGL's, as stylerf's (x right, y up, looking down -z), so the matrix's
// top 3x4 is Camera::c2w as it is. nerfstudio derives the intrinsics from fov and the render size alone:
// fx = fy = (H / 2) / tan(fov / 2), principal point at the image centre (W / 2, H / 2); "aspect" is the
// viewer's and only checked to be positive (the render size decides). "camera_type" may be left out
// (perspective); fisheye and equirectangular paths are refused. "seconds" is written, never needed: the
// frames are the entries, the video plays at "fps".
//
// stylerf's cameras may have fx != fy or an off-centre principal point (real captures). The writer then
// gives fov from fy, which is what nerfstudio renders (centred, square pixels), and keeps the exact
// intrinsics under the optional per-frame key "stylerf_intrinsics": {"fx", "fy", "cx", "cy"}; the reader
// takes them when present, so a path written here reads back bit for bit (every float is written with the
// decimal digits that parse back to the same float). They must agree with "fov" (fy within 1e-5 of the
// fov's): a file whose fov was edited elsewhere is refused, naming the key to remove.
//
// World frame: the cameras are taken in the scene's own world frame, the frame of the cameras stylerf
// loaded (what `stylerf render --export-camera-path` writes). nerfstudio's dataparser may recentre and
// rescale a capture (its dataparser_transforms.json), and stylerf's loaders of real captures normalise the
// poses as LLFF does, so a path drawn in nerfstudio's viewer over a COLMAP or nerfstudio capture is in
// another frame; over Blender scenes (kept as the file gives them by both) the frames agree.
#pragma once
#include <string>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

struct CameraPathFile {
  std::vector<Camera> cameras;  // one per frame, all render_width x render_height
  double fps = 30;              // the file's "fps" (30 when it has none)
};

// Reads a camera_path.json. Throws host::Error naming the file and what is wrong: not JSON, a missing or
// mistyped key, a matrix that is not 4x4 (16 numbers) or not a rigid camera-to-world transform, a value that
// is not finite, fov outside (0, 180) degrees, a render size outside [1, 16384], no frames, another camera
// type.
CameraPathFile read_camera_path_json(const std::string& path);

// The text of a camera_path.json for `cameras` (one size, at least one, finite), played at `fps`.
std::string camera_path_json_text(const std::vector<Camera>& cameras, double fps = 30);
// The same written to `path` atomically (a temporary file renamed into place).
void write_camera_path_json(const std::string& path, const std::vector<Camera>& cameras, double fps = 30);

// nerfstudio's intrinsics: the focal length in pixels of a vertical field of view over `height` rows.
double focal_from_fov(double fov_degrees, int height);
double fov_from_focal(double focal, int height);  // the inverse, in degrees

}  // namespace stylerf::scene
