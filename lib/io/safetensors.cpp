#include "lib/io/safetensors.hpp"

#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "host/error.hpp"
#include "host/files.hpp"
#include "host/tensor.hpp"

namespace stylerf::io {

using host::Error;
using json = nlohmann::json;

namespace {

// A header larger than this is not a weights file we wrote or could use (real ones are a few KB).
constexpr uint64_t kMaxHeaderBytes = 100u << 20;

uint64_t read_u64_le(const unsigned char* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

float f16_to_f32(uint16_t h) {
  uint32_t sign = uint32_t(h & 0x8000) << 16, exp = (h >> 10) & 0x1f, mant = h & 0x3ff, bits;
  if (exp == 0x1f) {
    bits = sign | 0x7f800000u | (mant << 13);  // inf / nan
  } else if (exp != 0) {
    bits = sign | ((exp + 112) << 23) | (mant << 13);  // normal: rebias 15 -> 127
  } else if (mant == 0) {
    bits = sign;
  } else {  // subnormal half: renormalise into a normal float
    int e = -1;
    do {
      mant <<= 1;
      ++e;
    } while (!(mant & 0x400));
    bits = sign | uint32_t(112 - e) << 23 | ((mant & 0x3ff) << 13);
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

float bf16_to_f32(uint16_t h) {
  uint32_t bits = uint32_t(h) << 16;  // bfloat16 is the top half of a float32
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

size_t dtype_size(const std::string& dtype) {
  if (dtype == "F32") return 4;
  if (dtype == "F16" || dtype == "BF16") return 2;
  if (dtype == "F64") return 8;
  return 0;
}

// Little-endian bytes -> floats (this code assumes a little-endian host, like every OpenCL target we run on).
std::vector<float> decode(const std::string& dtype, const unsigned char* p, size_t n) {
  std::vector<float> out(n);
  if (dtype == "F32") {
    if (n > 0) std::memcpy(out.data(), p, n * 4);  // an empty tensor: out.data() may be null
  } else if (dtype == "F64") {
    for (size_t i = 0; i < n; ++i) {
      double d;
      std::memcpy(&d, p + 8 * i, 8);
      out[i] = static_cast<float>(d);
    }
  } else {
    bool half = dtype == "F16";
    for (size_t i = 0; i < n; ++i) {
      uint16_t h = uint16_t(p[2 * i] | (p[2 * i + 1] << 8));
      out[i] = half ? f16_to_f32(h) : bf16_to_f32(h);
    }
  }
  return out;
}

}  // namespace

SafeTensors SafeTensors::load(const std::string& path, const std::string& missing_hint) {
  if (!std::filesystem::exists(path))
    throw Error("weights file " + path + " does not exist" + (missing_hint.empty() ? "" : "; " + missing_hint));
  std::string bytes = host::read_file(path);
  auto corrupt = [&](const std::string& what) {
    return Error("corrupt safetensors file " + path + ": " + what);
  };
  if (bytes.size() < 8) throw corrupt("file has " + std::to_string(bytes.size()) + " bytes, too short for a header");
  auto* base = reinterpret_cast<const unsigned char*>(bytes.data());
  uint64_t header_len = read_u64_le(base);
  if (header_len > kMaxHeaderBytes || header_len > bytes.size() - 8)
    throw corrupt("header length " + std::to_string(header_len) + " exceeds the file size " +
                  std::to_string(bytes.size()));
  json header;
  try {
    header = json::parse(bytes.begin() + 8, bytes.begin() + 8 + static_cast<std::ptrdiff_t>(header_len));
  } catch (const json::exception& e) {
    throw corrupt(std::string("header is not valid JSON (") + e.what() + ")");
  }
  if (!header.is_object()) throw corrupt("header is not a JSON object");

  SafeTensors st;
  st.path_ = path;
  const unsigned char* data = base + 8 + header_len;
  const uint64_t data_len = bytes.size() - 8 - header_len;
  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string& name = it.key();
    const json& e = it.value();
    if (name == "__metadata__") {
      if (e.is_object())
        for (auto m = e.begin(); m != e.end(); ++m)
          if (m.value().is_string()) st.metadata_[m.key()] = m.value().get<std::string>();
      continue;
    }
    auto bad = [&](const std::string& what) { return corrupt("tensor '" + name + "': " + what); };
    if (!e.is_object() || !e.contains("dtype") || !e.contains("shape") || !e.contains("data_offsets"))
      throw bad("entry needs dtype, shape and data_offsets");
    if (!e["dtype"].is_string()) throw bad("dtype is not a string");
    std::string dtype = e["dtype"].get<std::string>();
    size_t esize = dtype_size(dtype);
    if (esize == 0) throw bad("unsupported dtype " + dtype + " (F32, F16, BF16, F64 are read)");
    const json& js = e["shape"];
    const json& jo = e["data_offsets"];
    if (!js.is_array()) throw bad("shape is not an array");
    HostTensor t;
    uint64_t numel = 1;
    for (const auto& d : js) {
      if (!d.is_number_integer() || d.get<int64_t>() < 0) throw bad("shape has a non-integer or negative entry");
      t.shape.push_back(d.get<int64_t>());
      numel *= static_cast<uint64_t>(d.get<int64_t>());
      if (numel > data_len) throw bad("shape " + host::shape_str(t.shape) + " is larger than the file");
    }
    if (!jo.is_array() || jo.size() != 2 || !jo[0].is_number_unsigned() || !jo[1].is_number_unsigned())
      throw bad("data_offsets must be two non-negative integers");
    uint64_t b = jo[0].get<uint64_t>(), en = jo[1].get<uint64_t>();
    if (b > en || en > data_len)
      throw bad("data_offsets [" + std::to_string(b) + ", " + std::to_string(en) + "] out of range (data has " +
                std::to_string(data_len) + " bytes)");
    if (en - b != numel * esize)
      throw bad("data_offsets span " + std::to_string(en - b) + " bytes but shape " + host::shape_str(t.shape) +
                " of " + dtype + " needs " + std::to_string(numel * esize));
    t.data = decode(dtype, data + b, numel);
    st.tensors_.emplace(name, std::move(t));
  }
  return st;
}

std::vector<std::string> SafeTensors::names() const {
  std::vector<std::string> out;
  for (const auto& kv : tensors_) out.push_back(kv.first);
  return out;
}

const HostTensor& SafeTensors::get(const std::string& name) const {
  auto it = tensors_.find(name);
  if (it == tensors_.end()) throw Error(path_ + ": no tensor named '" + name + "'");
  return it->second;
}

const HostTensor& SafeTensors::get(const std::string& name, const std::vector<int64_t>& expected) const {
  const HostTensor& t = get(name);
  if (t.shape != expected)
    throw Error(path_ + ": tensor '" + name + "' has shape " + host::shape_str(t.shape) + ", expected " +
                host::shape_str(expected));
  return t;
}

void save_safetensors(const std::string& path, const std::map<std::string, HostTensor>& tensors,
                      const std::map<std::string, std::string>& metadata) {
  json header = json::object();
  if (!metadata.empty()) header["__metadata__"] = metadata;
  uint64_t offset = 0;
  for (const auto& [name, t] : tensors) {
    if (static_cast<int64_t>(t.data.size()) != host::shape_numel(t.shape))
      throw Error("save_safetensors " + path + ": tensor '" + name + "' has " + std::to_string(t.data.size()) +
                  " values for shape " + host::shape_str(t.shape));
    uint64_t n = t.data.size() * sizeof(float);
    header[name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {offset, offset + n}}};
    offset += n;
  }
  std::string h = header.dump();
  h.append((8 - h.size() % 8) % 8, ' ');  // pad so tensor data starts 8-byte aligned
  std::string out(8, '\0');
  uint64_t len = h.size();
  for (int i = 0; i < 8; ++i) out[i] = static_cast<char>((len >> (8 * i)) & 0xff);
  out += h;
  out.reserve(out.size() + offset);
  for (const auto& kv : tensors)  // std::map iteration order == the order offsets were assigned
    out.append(reinterpret_cast<const char*>(kv.second.data.data()), kv.second.data.size() * sizeof(float));
  host::write_file_atomic(path, out);
}

}  // namespace stylerf::io
