// Errors raised by the OpenCL runtime. Every OpenCL call goes through check(), so a failure names the
// call, what it was doing (kernel, buffer, program) and the OpenCL error code by name.
#pragma once
#include <CL/cl.h>

#include <stdexcept>
#include <string>

namespace stylerf::host {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A bad value of one named setting (a config field): `field` is its name as the library spells it
// ("lr_decoder"), so that a front end can name it its own way (the CLI's flag --lr-decoder, Python's
// keyword argument); what() is "<field> <problem>".
class SettingError : public Error {
 public:
  SettingError(const std::string& field, const std::string& problem)
      : Error(field + " " + problem), field_(field), problem_(problem) {}
  const std::string& field() const { return field_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string field_, problem_;
};

// The symbolic name of an OpenCL error code ("CL_OUT_OF_RESOURCES"), or "CL_ERROR(<n>)".
const char* cl_error_name(cl_int code);

// Throws Error("<call> failed for <context>: <CL_NAME>") when code != CL_SUCCESS.
void check(cl_int code, const char* call, const std::string& context = "");

}  // namespace stylerf::host
