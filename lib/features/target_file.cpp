#include "lib/features/target_file.hpp"

#include <cinttypes>
#include <cstdio>
#include <filesystem>

#include "host/error.hpp"

namespace stylerf::features {

using host::Error;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "stylerf-feature-targets";
constexpr const char* kTensor = "targets";
constexpr const char* kPlaceholder = "0000000000000000";  // the checksum's width, filled in by finish()

uint64_t fnv1a(uint64_t h, const uint8_t* p, size_t n) {
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}
constexpr uint64_t kFnvStart = 0xcbf29ce484222325ull;

std::string hex16(uint64_t v) {
  char s[17];
  std::snprintf(s, sizeof s, "%016" PRIx64, v);
  return s;
}

const char* safetensors_dtype(host::DType d) { return d == host::DType::F16 ? "F16" : "F32"; }

}  // namespace

TargetFileWriter::TargetFileWriter(const std::string& tmp_path, host::DType dtype, const host::Shape& shape,
                                   const json& meta)
    : path_(tmp_path), expected_(uint64_t(host::shape_numel(shape)) * host::dtype_size(dtype)), hash_(kFnvStart) {
  json header = json::object();
  header["__metadata__"] = {{"stylerf.format", kFormat}, {"stylerf.meta", meta.dump()}, {"stylerf.checksum", kPlaceholder}};
  header[kTensor] = {{"dtype", safetensors_dtype(dtype)}, {"shape", shape},
                     {"data_offsets", {uint64_t(0), expected_}}};
  std::string h = header.dump();
  h.append((8 - h.size() % 8) % 8, ' ');  // tensor data 8-byte aligned, as safetensors writers do
  const std::string key = std::string("\"stylerf.checksum\":\"") + kPlaceholder + "\"";
  const size_t at = h.find(key);
  if (at == std::string::npos) throw Error("target file " + path_ + ": header has no checksum field");
  checksum_at_ = std::streamoff(8 + at + key.size() - 1 - 16);
  out_.open(path_, std::ios::binary | std::ios::trunc);
  if (!out_) throw Error("target file " + path_ + ": cannot open for writing");
  uint8_t len[8];
  for (int i = 0; i < 8; ++i) len[i] = uint8_t((uint64_t(h.size()) >> (8 * i)) & 0xff);
  out_.write(reinterpret_cast<const char*>(len), 8);
  out_.write(h.data(), std::streamsize(h.size()));
}

void TargetFileWriter::append(const std::vector<uint8_t>& bytes) {
  if (written_ + bytes.size() > expected_)
    throw Error("target file " + path_ + ": more data than the header's " + std::to_string(expected_) + " bytes");
  out_.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  hash_ = fnv1a(hash_, bytes.data(), bytes.size());
  written_ += bytes.size();
}

void TargetFileWriter::finish() {
  if (written_ != expected_)
    throw Error("target file " + path_ + ": " + std::to_string(written_) + " of " + std::to_string(expected_) +
                " bytes written");
  out_.seekp(checksum_at_);
  out_ << hex16(hash_);
  out_.close();
  if (!out_) throw Error("target file " + path_ + ": write failed (disk full?)");
}

json read_target_file(const std::string& path, FeatureTargets& t) {
  auto bad = [&](const std::string& what) { return Error("target file " + path + ": " + what); };
  std::ifstream in(path, std::ios::binary);
  if (!in) throw bad("cannot open");
  uint8_t len8[8];
  if (!in.read(reinterpret_cast<char*>(len8), 8)) throw bad("shorter than a safetensors header");
  uint64_t hlen = 0;
  for (int i = 0; i < 8; ++i) hlen |= uint64_t(len8[i]) << (8 * i);
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec || hlen > size - 8) throw bad("header length " + std::to_string(hlen) + " exceeds the file");
  std::string h(hlen, '\0');
  if (!in.read(h.data(), std::streamsize(hlen))) throw bad("truncated header");
  json header;
  try {
    header = json::parse(h);
  } catch (const std::exception& e) {
    throw bad(std::string("header is not JSON (") + e.what() + ")");
  }
  const json md = header.value("__metadata__", json::object());
  if (md.value("stylerf.format", std::string()) != kFormat) throw bad("not a stylerf feature-target file");
  if (!header.contains(kTensor)) throw bad("no tensor 'targets'");
  const json& e = header[kTensor];
  if (e.value("dtype", std::string()) != safetensors_dtype(t.maps.dtype()))
    throw bad("targets are " + e.value("dtype", std::string("?")) + ", expected " + safetensors_dtype(t.maps.dtype()));
  const std::vector<int64_t> shape = e.value("shape", std::vector<int64_t>{});
  if (shape != t.maps.shape())
    throw bad("targets have shape " + host::shape_str(shape) + ", expected " + host::shape_str(t.maps.shape()));
  if (size != 8 + hlen + t.maps.bytes())
    throw bad(std::to_string(size) + " bytes, expected " + std::to_string(8 + hlen + t.maps.bytes()) + " (truncated?)");
  std::vector<uint8_t> view(view_bytes(t));
  uint64_t hash = kFnvStart;
  for (int v = 0; v < t.views(); ++v) {
    if (!in.read(reinterpret_cast<char*>(view.data()), std::streamsize(view.size())))
      throw bad("truncated at view " + std::to_string(v));
    hash = fnv1a(hash, view.data(), view.size());
    put_view(t, v, view);
  }
  const std::string want = md.value("stylerf.checksum", std::string());
  if (hex16(hash) != want) throw bad("corrupt: checksum " + hex16(hash) + " does not match the stored " + want);
  try {
    return json::parse(md.value("stylerf.meta", std::string("{}")));
  } catch (const std::exception& ex) {
    throw bad(std::string("metadata is not JSON (") + ex.what() + ")");
  }
}

}  // namespace stylerf::features
