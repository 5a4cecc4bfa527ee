// Files compiled into the binary at build time (see cmake/embed_files.cmake).
#pragma once
#include <string>
#include <vector>

namespace stylerf::host {

struct EmbeddedFile {
  const char* name;  // kernels/<name>.cl
  std::string text;
};

const std::vector<EmbeddedFile>& embedded_kernels();
// tuning/clblast.json as it was when the binary was built.
const std::string& embedded_tuning_db();

}  // namespace stylerf::host
