// A 64-bit content hash for cache keys: fast enough to run over every training image and the VGG weights
// file each time targets are looked up (8 bytes per step, not 1), and stable across runs and machines
// (little-endian words, fixed constants). Not cryptographic: it guards against stale caches, not attackers.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace stylerf::features {

class ContentHash {
 public:
  ContentHash& bytes(const void* data, size_t n);
  // Length-prefixed, so ("ab", "c") and ("a", "bc") hash differently.
  ContentHash& text(const std::string& s);
  ContentHash& number(int64_t v);
  ContentHash& floats(const std::vector<float>& v);
  // The whole file's bytes plus its size; throws host::Error naming the file when it cannot be read.
  ContentHash& file(const std::string& path);

  uint64_t value() const;
  std::string hex() const;  // 16 lower-case hex digits

 private:
  void word(uint64_t w);
  uint64_t h_ = 0x6a09e667f3bcc909ull;
  uint64_t count_ = 0;
};

}  // namespace stylerf::features
