// SHA-256 (FIPS 180-4) of bytes and files, to check downloaded weights against the sums their set-up
// recorded in manifest.json. Plain C++: no crypto library is needed for an integrity check.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

namespace stylerf::io {

class Sha256 {
 public:
  Sha256();
  void update(const void* data, size_t n);
  std::string hex();  // finishes: 64 lower-case hex digits

 private:
  void block(const unsigned char* p);
  uint32_t h_[8];
  unsigned char buf_[64];
  size_t used_ = 0;
  uint64_t bits_ = 0;
};

std::string sha256_hex(const std::string& bytes);
// Streams the file; throws host::Error naming it when it cannot be read.
std::string sha256_file(const std::string& path);

}  // namespace stylerf::io
