// `stylerf make-scene`: renders AnalyticScene::objects() into a Blender-format dataset with known depth.
//
// Layout of DIR:
//   transforms_{train,val,test}.json  camera_angle_x, frames[{file_path, transform_matrix, depth_path}],
//                                     plus near, far, aabb and "generator": "stylerf make-scene"
//   {train,val,test}/r_<i>.png        8-bit RGBA, straight alpha, alpha 0 on the background
//   {train,val,test}/r_<i>_depth.exr  one float channel "Y": distance from the camera centre along the
//                                     unit pixel-centre ray (rays.hpp convention); 0 where the ray misses
// Cameras sit on a sphere (golden-angle spiral from 70 degrees above to 35 below the horizon) looking at
// the origin with +z up; view i goes to val when i % 10 == 0, to test when i % 10 == 5, else train
// (60 views -> 48/6/6). The whole directory is written beside DIR and renamed into place at the end, so
// a failure never leaves a half-written scene; an existing DIR is replaced only if it is empty or was
// made by make-scene.
#pragma once
#include <string>

namespace stylerf::scene {

struct MakeSceneOptions {
  int size = 128;               // width = height in pixels
  int views = 60;
  float radius = 4.0f;          // camera distance from the origin
  float camera_angle_x = 0.9f;  // horizontal field of view, radians
  int supersample = 2;          // per axis, for colour and alpha
  // AnalyticScene::textured() (noise-textured shapes on a floor of radius 2.4, partly outside the box) seen
  // from 60 to 15 degrees above the horizon: images structure from motion registers (the import's tests).
  bool textured = false;
};

struct MakeSceneSummary {
  int train = 0, val = 0, test = 0;
  double seconds = 0;
};

MakeSceneSummary make_scene(const std::string& dir, const MakeSceneOptions& opts = {});

}  // namespace stylerf::scene
