#pragma once
// Which blocks of a feature map need more than their centre ray.
//
// The fast profile renders one ray a 4x4 block; inference averages n x n sub-rays a block so that fine
// geometry (fern's leaves) moves through the map smoothly instead of flickering in and out of the block
// centres (render_camera_content). Where the map is smooth the n x n average of a symmetric sub-ray
// pattern equals the centre ray for anything that varies linearly across the block, so only the blocks
// whose centre differs from a neighbour's need the other sub-rays: on lego most blocks are empty space or
// a flat face. This is the classic adaptive anti-aliasing test (contrast against the neighbours), on
// what the decoder sees: the composited content and the opacity.
#include <cstdint>
#include <vector>

namespace stylerf::model {

// Inference default of render_camera_content's refine_contrast (measured: docs/results.md, "Rays a block
// only where the map has edges").
constexpr float kRefineContrast = 0.15f;

// c: [w*h][channels] centre-ray content, acc: [w*h] opacity. Block b is refined when, against any of its
// 8 neighbours n, either |acc_b - acc_n| or the RMS over channels of (c_bk - c_nk) / s_k exceeds
// `contrast`, s_k being channel k's standard deviation over the map (a channel constant over the map
// never triggers). contrast <= 0 refines every block (the exact n x n average). Returns 1 per refined
// block.
std::vector<uint8_t> blocks_to_refine(const std::vector<float>& c, int channels, const std::vector<float>& acc, int w,
                                      int h, float contrast);

}  // namespace stylerf::model
