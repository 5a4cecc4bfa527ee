// The viewer's page (examples/stylerf/view_page/), embedded at build time by cmake/embed_page.cmake.
#pragma once
#include <string>
#include <vector>

namespace stylerf::cli {

struct PageFile {
  const char* path;  // "/index.html", "/app.js", ...
  const char* type;  // its Content-Type
  std::string body;
};
const std::vector<PageFile>& view_page_files();

}  // namespace stylerf::cli
