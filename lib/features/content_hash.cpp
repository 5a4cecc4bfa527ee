#include "lib/features/content_hash.hpp"

#include <cstring>
#include <fstream>

#include "host/error.hpp"

namespace stylerf::features {

namespace {
// The 64-bit finaliser of MurmurHash3 (a bijection that spreads every input bit over the word).
uint64_t mix(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdull;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ull;
  x ^= x >> 33;
  return x;
}
}  // namespace

void ContentHash::word(uint64_t w) {
  // Multiply-rotate chain: each word changes the state through an odd multiplier, so reordering or
  // changing any word changes the result.
  h_ ^= mix(w + 0x9e3779b97f4a7c15ull * ++count_);
  h_ = (h_ << 27 | h_ >> 37) * 0x100000001b3ull + 0x52dce729ull;
}

ContentHash& ContentHash::bytes(const void* data, size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    uint64_t w;
    std::memcpy(&w, p + i, 8);  // little-endian hosts only (x86, arm64): the cache is per machine anyway
    word(w);
  }
  uint64_t tail = 0;
  for (size_t k = 0; i + k < n; ++k) tail |= uint64_t(p[i + k]) << (8 * k);
  word(tail ^ (uint64_t(n & 7) << 60));
  return *this;
}

ContentHash& ContentHash::text(const std::string& s) {
  number(static_cast<int64_t>(s.size()));
  return bytes(s.data(), s.size());
}

ContentHash& ContentHash::number(int64_t v) {
  word(static_cast<uint64_t>(v));
  return *this;
}

ContentHash& ContentHash::floats(const std::vector<float>& v) {
  number(static_cast<int64_t>(v.size()));
  return bytes(v.data(), v.size() * sizeof(float));
}

ContentHash& ContentHash::file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw host::Error("cannot hash " + path + ": the file cannot be opened");
  std::vector<char> buf(size_t(1) << 20);  // 1 MiB chunks (a multiple of 8, so words never straddle reads)
  int64_t total = 0;
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const std::streamsize got = in.gcount();
    if (got <= 0) break;
    bytes(buf.data(), size_t(got));
    total += got;
  }
  if (in.bad()) throw host::Error("cannot hash " + path + ": read error");
  return number(total);
}

uint64_t ContentHash::value() const { return mix(h_ ^ count_); }

std::string ContentHash::hex() const {
  static const char* digits = "0123456789abcdef";
  std::string s(16, '0');
  uint64_t v = value();
  for (int i = 15; i >= 0; --i, v >>= 4) s[size_t(i)] = digits[v & 15];
  return s;
}

}  // namespace stylerf::features
