#include "lib/nn/decoder.hpp"

#include "host/error.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::nn {

using host::Error;

namespace {
ConvStackSpec make_spec(std::vector<int> channels, std::vector<bool> upsample_after, const std::string& name_prefix,
                        int group) {
  ConvStackSpec s;
  s.channels = std::move(channels);
  s.upsample_after = std::move(upsample_after);
  s.pad = Padding::Reflect;
  s.name_prefix = name_prefix;
  s.group = group;
  return s;
}
}  // namespace

ConvStackSpec adain_decoder_spec(const std::string& name_prefix, int group) {
  return make_spec({512, 256, 256, 256, 256, 128, 128, 64, 64, 3},
                   {true, false, false, false, true, false, true, false, false}, name_prefix, group);
}

ConvStackSpec plain_decoder_spec(const std::string& name_prefix, int group) {
  return make_spec({256, 256, 256, 256, 128, 128, 64, 64, 3}, {}, name_prefix, group);
}

ConvStackSpec fast_decoder_spec(const std::string& name_prefix, int group) {
  return make_spec({256, 256, 256, 256, 128, 128, 64, 64, 3}, {false, false, false, true, false, true, false, false},
                   name_prefix, group);
}

ConvStack load_adain_decoder(const std::string& path, const std::string& name_prefix, int group) {
  const std::string file = path.empty() ? weights_path(kDecoderWeightsFile) : path;
  ConvStack d = ConvStack::from_file(file, name_prefix, group);
  const ConvStackSpec want = adain_decoder_spec();
  if (!d.spec().same_architecture(want))
    throw Error(file + ": not AdaIN's decoder: the file holds " + d.spec().describe() + ", expected " +
                want.describe());
  return d;
}

ConvStack fast_decoder_from_adain(const ConvStack& adain, const std::string& name_prefix, int group) {
  const ConvStackSpec want = adain_decoder_spec();
  if (adain.empty() || !adain.spec().same_architecture(want))
    throw Error("fast_decoder_from_adain: the source is not AdaIN's decoder: it is " +
                (adain.empty() ? std::string("empty") : adain.spec().describe()) + ", expected " + want.describe());
  ConvStack fast = adain.tail(1, name_prefix, group);  // drop conv 1 (512 -> 256) and its upsampling
  // By construction; checked so that a change to either spec cannot silently diverge.
  if (!fast.spec().same_architecture(fast_decoder_spec()))
    throw Error("fast_decoder_from_adain: AdaIN's convs 2..9 are " + fast.spec().describe() +
                ", not the fast decoder's " + fast_decoder_spec().describe());
  return fast;
}

}  // namespace stylerf::nn
