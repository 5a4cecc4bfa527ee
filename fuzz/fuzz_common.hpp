// Shared by the harnesses: the input goes to a file (the readers take paths), then the reader runs; a
// host::Error is the expected refusal, anything else escapes and libFuzzer reports it.
#pragma once
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <string>

#include "host/error.hpp"

namespace fuzz {

inline std::string scratch(const std::string& name) {
  static const std::string dir = [] {
    const std::string d = "/tmp/stylerf-fuzz-" + std::to_string(::getpid());
    ::mkdir(d.c_str(), 0700);
    return d;
  }();
  return dir + "/" + name;
}

inline std::string write(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = scratch(name);
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(data), std::streamsize(size));
  return path;
}

template <class F>
void expect_clean(F&& f) {
  try {
    f();
  } catch (const stylerf::host::Error&) {
    // a clear refusal: fine
  }
}

}  // namespace fuzz
