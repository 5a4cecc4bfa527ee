// The decoders StyleRF uses, all nn::ConvStacks (lib/nn/conv_stack.hpp): features -> RGB.
//
//  - AdaIN's pretrained decoder (decoder.pth, converted by scripts/fetch_weights.sh): relu4_1 features,
//    512 channels, at 1/8 size -> RGB. Nine reflect-padded convs, Sequential modules 1, 5, 8, 11, 14, 18,
//    21, 25, 28: 512-256, up, 256-256 x3, 256-128, up, 128-128, 128-64, up, 64-64, 64-3.
//  - The paper profile's PlainDecoder: relu3_1-like features (256) at full size -> RGB, eight reflect
//    convs 256-256-256-256-128-128-64-64-3, no upsampling (StyleRF's own decoder, trained from scratch).
//  - The fast profile's decoder: relu3_1 features (256) at their native 1/4 size -> RGB at full size,
//    AdaIN's decoder after its relu4_1 stage, i.e. its convs 2..9 (modules 5 ... 28): 256-256 x3, 256-128,
//    up, 128-128, 128-64, up, 64-64, 64-3. Only the first conv (module 1, 512 -> 256) and the upsampling
//    after it are dropped; every other weight is AdaIN's, as a starting point for fine-tuning.
#pragma once
#include <string>

#include "lib/nn/conv_stack.hpp"

namespace stylerf::nn {

ConvStackSpec adain_decoder_spec(const std::string& name_prefix = "adain_decoder.", int group = 0);
ConvStackSpec plain_decoder_spec(const std::string& name_prefix = "decoder.", int group = 0);
ConvStackSpec fast_decoder_spec(const std::string& name_prefix = "decoder.", int group = 0);

// AdaIN's decoder from `path` (default: weights_path(kDecoderWeightsFile)). Errors name the file, and
// the set-up command when it is missing; a file of another architecture is refused, naming both.
ConvStack load_adain_decoder(const std::string& path = "", const std::string& name_prefix = "adain_decoder.",
                             int group = 0);

// The fast profile's decoder initialised from AdaIN's (layers 2..9, weights copied: fine-tuning it does
// not touch `adain`). An Error when `adain` does not have AdaIN's architecture.
ConvStack fast_decoder_from_adain(const ConvStack& adain, const std::string& name_prefix = "decoder.",
                                  int group = 0);

}  // namespace stylerf::nn
