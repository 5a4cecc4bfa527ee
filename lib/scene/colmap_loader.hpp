// Scenes from COLMAP and nerfstudio, as a user who already ran one of them has them.
//
// COLMAP ("colmap-forward" / "colmap-object"): a folder with sparse/0/ (or sparse/) holding cameras,
// images and points3D (.bin or .txt), and images/ with the files the model names: what
// `colmap image_undistorter` writes. Cameras must project as pinholes (SIMPLE_PINHOLE, PINHOLE, or a
// distorted model whose distortion is zero); otherwise the error says to run image_undistorter. Several
// cameras (intrinsics per image) are fine; all images must end up one size. Images are taken in name
// order; --downsample N reads images_N/ when present, else resizes images/. Depth bounds per image are
// LLFF's: the 0.1 and 99.9 percentiles of the depths of the 3D points that image observes. The forward-
// facing/object-centric decision, normalisation, near/far and box are the LLFF loader's
// (capture_geometry.hpp). Test views: every 8th image in name order.
//
// nerfstudio ("nerfstudio-forward" / "nerfstudio-object"): a folder with transforms.json (not Blender's
// transforms_train.json): intrinsics fl_x, fl_y, cx, cy, w, h and distortion k1..k4, p1, p2 at the top
// level or per frame (a frame's own override), frames with file_path and transform_matrix (camera-to-world,
// OpenGL axes, 4x4), optional camera_model (PINHOLE, or OPENCV with zero distortion) and applied_transform
// (accepted and noted). Non-zero distortion or a fisheye/equirectangular model is refused. There are no
// depth bounds in the file, so near/far and the box follow the layout (see capture_geometry.hpp). Frames
// are taken in file_path order; test views every 8th.
#pragma once
#include <string>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

Scene load_colmap(const std::string& dir, const LoadOptions& opts);
Scene load_nerfstudio(const std::string& dir, const LoadOptions& opts);

}  // namespace stylerf::scene
