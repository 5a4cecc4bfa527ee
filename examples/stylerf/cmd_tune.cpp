// stylerf tune [--quick] [-o FILE] [--from-dir DIR] [--skip-clblast] [--skip-own] [--device D]
//
// Tunes GEMM for the current device and merges the result into a tuning database file:
//  1. CLBlast: runs CLBlast's tuners (clblast_tuner_* from clblast-utils, found on PATH) in a temporary
//     directory, or reads their clblast_*.json results from --from-dir, and keeps the fastest
//     parameters per kernel family (Xgemm, XgemmDirect, Copy, Pad, Transpose, Padtranspose).
//  2. Own kernel: a small search over tile shapes, K chunk and work-group size of kernels/gemm.cl,
//     timed on reduced versions of the decoder's forward, dX and dW GEMMs.
//  3. Measures own, CLBlast tuned and CLBlast defaults on the same shapes and records the fastest as the
//     device's recommended engine (what GemmEngine::Auto uses).
// The file is $STYLERF_CACHE_DIR/clblast-tuning.json (or ~/.cache/stylerf/...) unless -o names one
// (e.g. the repository's tuning/clblast.json); other devices' entries in it are kept.
//
// Note on CLBlast 1.5.3's tuners: "-fraction F" explores (number of configurations) / F, so F > 1
// samples and F < 1 pads the list with empty configurations. The defaults (all of the fixed set, 1/512
// of the random set) are what a full run uses; --quick divides further.
#include <CL/cl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <boost/program_options.hpp>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <vector>

#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/error.hpp"
#include "host/files.hpp"
#include "host/gemm.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "host/tuning_db.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;
using namespace stylerf::host;

namespace {

std::string find_on_path(const std::string& exe) {
  const char* path = std::getenv("PATH");
  std::stringstream s(path ? path : "");
  std::string dir;
  while (std::getline(s, dir, ':')) {
    if (dir.empty()) continue;
    const std::string p = dir + "/" + exe;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return "";
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// CLBlast's tuners take -platform P -device D: our device's position in OpenCL's lists.
std::pair<int, int> platform_and_device_index(const DeviceInfo& dev) {
  cl_uint np = 0;
  check(clGetPlatformIDs(0, nullptr, &np), "clGetPlatformIDs");
  std::vector<cl_platform_id> platforms(np);
  check(clGetPlatformIDs(np, platforms.data(), nullptr), "clGetPlatformIDs");
  for (cl_uint p = 0; p < np; ++p) {
    if (platforms[p] != dev.platform) continue;
    cl_uint nd = 0;
    check(clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, 0, nullptr, &nd), "clGetDeviceIDs");
    std::vector<cl_device_id> devices(nd);
    check(clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, nd, devices.data(), nullptr), "clGetDeviceIDs");
    for (cl_uint d = 0; d < nd; ++d)
      if (devices[d] == dev.id) return {static_cast<int>(p), static_cast<int>(d)};
  }
  throw Error("cannot find the OpenCL platform/device index of '" + dev.name + "' for CLBlast's tuners");
}

struct TunerRun {
  std::string exe, args;
};

const char* const kTuners[] = {"clblast_tuner_xgemm",          "clblast_tuner_xgemm_direct",
                               "clblast_tuner_copy_fast",      "clblast_tuner_copy_pad",
                               "clblast_tuner_transpose_fast", "clblast_tuner_transpose_pad"};

void require_tuners() {
  std::string missing;
  for (const char* t : kTuners)
    if (find_on_path(t).empty()) missing += std::string(" ") + t;
  if (!missing.empty())
    throw Error("CLBlast's tuners are not on PATH (missing:" + missing +
                "). Install them (Debian/Ubuntu: apt install clblast-utils), or pass --from-dir DIR with "
                "their clblast_*.json results, or --skip-clblast.");
}

// Runs CLBlast's tuners in dir; returns the number that failed. Output goes to <dir>/<tuner>.log.
int run_clblast_tuners(const std::string& dir, const DeviceInfo& dev, bool quick) {
  const auto [p, d] = platform_and_device_index(dev);
  const std::string common = "-platform " + std::to_string(p) + " -device " + std::to_string(d) + " -precision 32";
  // Quick: smaller problems and fewer configurations (see the note on -fraction at the top).
  // Xgemm's fixed set has ~600 configurations and its random sets ~120000 (GEMMK 0) and ~16000 (GEMMK 1),
  // so quick samples 1/4096: none of the fixed set, ~30 + ~4 random ones. It finds far weaker parameters
  // than a full run (which takes tens of minutes); use it to check the set-up, not for the database.
  const std::string gemm_q = quick ? " -m 512 -n 512 -k 512 -fraction 4096 -runs 1" : " -runs 2";
  // XgemmDirect: ~50 fixed and ~8400 random configurations; quick samples ~16 random ones.
  const std::string small_q = quick ? " -fraction 4 -runs 1" : " -runs 2";
  const std::vector<TunerRun> runs = {
      {"clblast_tuner_xgemm", common + gemm_q},
      {"clblast_tuner_xgemm_direct", common + (quick ? " -m 256 -n 256 -k 256 -fraction 512 -runs 1" : " -runs 2")},
      {"clblast_tuner_copy_fast", common + small_q},
      {"clblast_tuner_copy_pad", common + small_q},
      {"clblast_tuner_transpose_fast", common + small_q},
      {"clblast_tuner_transpose_pad", common + small_q},
  };
  int failed = 0;
  for (const auto& r : runs) {
    const auto t0 = std::chrono::steady_clock::now();
    std::cout << "  " << r.exe << " " << r.args << " ... " << std::flush;
    const std::string cmd = "cd " + quote(dir) + " && " + quote(find_on_path(r.exe)) + " " + r.args + " > " +
                            quote(r.exe + ".log") + " 2>&1";
    const int rc = std::system(cmd.c_str());
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << (rc == 0 ? "done" : "FAILED (see " + dir + "/" + r.exe + ".log)") << " in " << std::fixed
              << std::setprecision(0) << s << " s\n";
    if (rc != 0) ++failed;
  }
  return failed;
}

// Best parameters per CLBlast kernel family from every clblast_*_32.json in dir.
std::map<std::string, ClblastTunerResult> collect_tuner_results(const std::string& dir, const DeviceInfo& dev) {
  std::map<std::string, ClblastTunerResult> best;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("clblast_", 0) != 0 || entry.path().extension() != ".json") continue;
    ClblastTunerResult r;
    try {
      r = parse_clblast_tuner_json(read_file(entry.path().string()), entry.path().string());
    } catch (const Error& e) {
      std::cerr << "  skipping " << name << ": " << e.what() << "\n";
      continue;
    }
    if (!r.device.empty() && r.device != dev.name)
      std::cerr << "  note: " << name << " was tuned on '" << r.device << "', not '" << dev.name << "'\n";
    std::cout << "  " << name << ": " << r.kernel << " best " << r.best_ms << " ms\n";
    auto it = best.find(r.kernel);
    if (it == best.end() || r.best_ms / r.work < it->second.best_ms / it->second.work) best[r.kernel] = r;
  }
  return best;
}

struct GemmShape {
  const char* name;
  Trans ta, tb;
  int M, N, K;
};

// Reduced decoder GEMMs (256 channels, 3x3 kernel): forward, dX, dW.
std::vector<GemmShape> search_shapes(bool quick) {
  const int hw = quick ? 4096 : 16384;
  return {{"fwd", Trans::No, Trans::No, 256, hw, 2304},
          {"dX", Trans::Yes, Trans::No, 2304, hw, 256},
          {"dW", Trans::No, Trans::Yes, 256, 2304, hw}};
}

struct ShapeBuffers {
  GemmShape s;
  Tensor A, B, C;
};

std::vector<ShapeBuffers> make_buffers(const std::vector<GemmShape>& shapes) {
  std::vector<ShapeBuffers> out;
  for (const auto& s : shapes) {
    const int64_t a = int64_t(s.M) * s.K, b = int64_t(s.K) * s.N, c = int64_t(s.M) * s.N;
    out.push_back({s, Tensor::full({a}, 0.5f, "tune A"), Tensor::full({b}, 0.25f, "tune B"), Tensor::zeros({c}, "tune C")});
  }
  return out;
}

// Total best-of-`reps` seconds over the shapes for one way of running GEMM.
template <class F>
double time_shapes(std::vector<ShapeBuffers>& bufs, int reps, F&& run) {
  double total = 0.0;
  for (auto& b : bufs) {
    const GemmShape& s = b.s;
    const int lda = s.ta == Trans::Yes ? s.M : s.K, ldb = s.tb == Trans::Yes ? s.K : s.N;
    auto once = [&] {
      run(s, b.A.mem(), lda, b.B.mem(), ldb, b.C.mem());
      Runtime::instance().finish();
    };
    once();  // warm-up: compiles
    double best = 1e30;
    for (int r = 0; r < reps; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      once();
      best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    total += best;
  }
  return total;
}

double flops_of(const std::vector<GemmShape>& shapes) {
  double f = 0;
  for (const auto& s : shapes) f += 2.0 * s.M * s.N * double(s.K);
  return f;
}

double time_own(std::vector<ShapeBuffers>& bufs, int reps, const OwnGemmParams& p) {
  return time_shapes(bufs, reps, [&](const GemmShape& s, cl_mem A, int lda, cl_mem B, int ldb, cl_mem C) {
    gemm_own_with(p, s.ta, s.tb, s.M, s.N, s.K, 1.0f, A, 0, lda, B, 0, ldb, 0.0f, C, 0, s.N);
  });
}

double time_engine(std::vector<ShapeBuffers>& bufs, int reps, GemmEngine e) {
  return time_shapes(bufs, reps, [&](const GemmShape& s, cl_mem A, int lda, cl_mem B, int ldb, cl_mem C) {
    gemm(s.ta, s.tb, s.M, s.N, s.K, 1.0f, A, 0, lda, B, 0, ldb, 0.0f, C, 0, s.N, e);
  });
}

// Coordinate search: tile shape first (the register tile matters most), then K chunk, work-group size and
// column tiles per work-item.
OwnGemmParams search_own(std::vector<ShapeBuffers>& bufs, double flops, bool quick, double* best_gflops) {
  const int reps = quick ? 2 : 3;
  OwnGemmParams best;
  double best_t = 1e30;
  auto consider = [&](const OwnGemmParams& p) {
    try {
      p.validate();
      const double t = time_own(bufs, reps, p);
      std::cout << "    " << std::left << std::setw(30) << p.describe() << std::right << std::fixed
                << std::setprecision(1) << std::setw(8) << flops / t * 1e-9 << " GFLOP/s\n";
      if (t < best_t) {
        best_t = t;
        best = p;
      }
    } catch (const std::exception& e) {
      std::cout << "    " << p.describe() << ": failed: " << e.what() << "\n";
    }
  };
  // 16 vector registers (AVX2) fit 12 accumulators plus operands; 32 (AVX-512) fit wider tiles.
  std::vector<std::array<int, 3>> tiles = {{6, 8, 2}, {4, 8, 3}, {8, 8, 1}, {3, 8, 4}, {4, 8, 2}, {6, 16, 1}};
  if (!quick) {
    for (std::array<int, 3> t : std::vector<std::array<int, 3>>{{5, 8, 2}, {2, 8, 6}, {12, 8, 1}, {8, 16, 2}, {14, 16, 1}, {4, 16, 2}})
      tiles.push_back(t);
  }
  std::cout << "  tile shapes (mr x vw*nv):\n";
  for (const auto& t : tiles) consider(OwnGemmParams{t[0], t[1], t[2], 512, 1, 1});
  std::cout << "  K chunk:\n";
  const OwnGemmParams tile = best;
  for (int kc : quick ? std::vector<int>{256, 1024} : std::vector<int>{128, 256, 1024, 2048, 0})
    consider(OwnGemmParams{tile.mr, tile.vw, tile.nv, kc, tile.wg, tile.qt});
  std::cout << "  work-group size:\n";
  const OwnGemmParams chunk = best;
  for (int wg : quick ? std::vector<int>{4} : std::vector<int>{2, 4, 8})
    consider(OwnGemmParams{chunk.mr, chunk.vw, chunk.nv, chunk.kc, wg, chunk.qt});
  std::cout << "  column tiles per work-item:\n";
  const OwnGemmParams group = best;
  for (int qt : quick ? std::vector<int>{4} : std::vector<int>{2, 4, 8})
    consider(OwnGemmParams{group.mr, group.vw, group.nv, group.kc, group.wg, qt});
  *best_gflops = flops / best_t * 1e-9;
  return best;
}

std::string now_utc() {
  std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

std::string fmt(double v) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(1) << v;
  return o.str();
}

int run_tune(int argc, char** argv) {
  std::string out, device, from_dir;
  bool quick = false, skip_clblast = false, skip_own = false, keep = false;
  po::options_description desc("stylerf tune [options]: tune GEMM (CLBlast + own kernel) for this device");
  desc.add_options()("help,h", "show this help")("quick", po::bool_switch(&quick), "fewer configurations (minutes)")(
      "output,o", po::value(&out)->default_value(user_tuning_path()), "database file to merge into")(
      "from-dir", po::value(&from_dir), "use clblast_*.json tuner results from DIR instead of running the tuners")(
      "skip-clblast", po::bool_switch(&skip_clblast), "keep the existing CLBlast parameters")(
      "skip-own", po::bool_switch(&skip_own), "keep the existing own-kernel parameters")(
      "keep-dir", po::bool_switch(&keep), "keep the tuners' temporary directory")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  stylerf::cli::apply_renamed_flags("tune", argc, argv, {{"--out", "--output"}});
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help")) {
    stylerf::cli::print_help(std::cout, "tune", desc);
    return 0;
  }
  stylerf::cli::init_runtime(device, false);
  const DeviceInfo& dev = Runtime::instance().device();
  if (out.empty()) throw std::runtime_error("-o: an empty file name");
  std::cout << "device: " << dev.describe() << "\ndatabase: " << out << (quick ? " (quick)" : "") << "\n";

  // Start from the file's current content and this device's current entry (embedded or user).
  TuningDb db;
  if (fs::exists(out)) db = TuningDb::parse(read_file(out), out);
  DeviceTuning entry;
  if (const DeviceTuning* cur = db.find(dev.name)) entry = *cur;
  else if (const DeviceTuning* act = active_device_tuning()) entry = *act;

  if (!skip_clblast) {
    std::cout << "\n[1/3] CLBlast tuners\n";
    std::string dir = from_dir;
    if (dir.empty()) {
      require_tuners();
      std::string tmpl = (fs::temp_directory_path() / "stylerf-tune-XXXXXX").string();
      if (!mkdtemp(tmpl.data())) throw Error("cannot create a temporary directory for the tuners");
      dir = tmpl;
      std::cout << "  working in " << dir << "\n";
      const int failed = run_clblast_tuners(dir, dev, quick);
      if (failed) std::cerr << "  " << failed << " tuner(s) failed; using the results that exist\n";
    }
    auto results = collect_tuner_results(dir, dev);
    if (results.empty()) throw Error("no CLBlast tuner results in " + dir);
    for (const auto& [kernel, r] : results) entry.clblast[kernel] = r.params;
    entry.notes["clblast_source"] = (from_dir.empty() ? std::string("stylerf tune") : "tuner results in " + from_dir) +
                                    (quick ? " (quick)" : "") + ", " + now_utc();
    if (from_dir.empty() && !keep) fs::remove_all(dir);
    else std::cout << "  tuner files kept in " << dir << "\n";
  }

  const auto shapes = search_shapes(quick);
  const double flops = flops_of(shapes);
  auto bufs = make_buffers(shapes);
  std::cout << "\nshapes for the own-kernel search and engine choice:";
  for (const auto& s : shapes)
    std::cout << " " << s.name << " " << s.M << "x" << s.N << "x" << s.K << (s.ta == Trans::Yes ? "(TN)" : "")
              << (s.tb == Trans::Yes ? "(NT)" : "");
  std::cout << "\n";

  double own_gflops = 0.0;
  if (!skip_own) {
    std::cout << "\n[2/3] own kernel search\n";
    entry.own_gemm = search_own(bufs, flops, quick, &own_gflops);
    std::cout << "  best: " << entry.own_gemm->describe() << " at " << fmt(own_gflops) << " GFLOP/s\n";
  } else {
    own_gflops = flops / time_own(bufs, 2, entry.own_gemm.value_or(OwnGemmParams{})) * 1e-9;
  }

  std::cout << "\n[3/3] engine choice (same shapes, this run)\n";
  use_device_tuning(entry);
  const double tuned = flops / time_engine(bufs, 1, GemmEngine::ClblastTuned) * 1e-9;
  const double deflt = flops / time_engine(bufs, 1, GemmEngine::ClblastDefault) * 1e-9;
  // host-blas runs only on CPU devices of builds with a CBLAS; elsewhere it is not a candidate.
  const double hblas = host_blas_usable() ? flops / time_engine(bufs, 1, GemmEngine::HostBlas) * 1e-9 : 0.0;
  std::string measured = "own " + fmt(own_gflops) + ", clblast-tuned " + fmt(tuned) + ", clblast-default " + fmt(deflt);
  if (host_blas_usable()) measured += ", host-blas " + fmt(hblas);
  std::cout << "  " << measured << " GFLOP/s\n";
  const std::pair<double, const char*> candidates[] = {
      {own_gflops, "own"}, {tuned, "clblast-tuned"}, {deflt, "clblast-default"}, {hblas, "host-blas"}};
  entry.recommended_engine = std::max_element(std::begin(candidates), std::end(candidates))->second;
  entry.notes["measured_gflops"] = measured + " (decoder GEMMs at " + std::to_string(shapes[0].N) + " pixels, " +
                                   now_utc() + ")";
  entry.notes["driver"] = dev.driver;
  std::cout << "  recommended engine: " << entry.recommended_engine << "\n";

  db.set(dev.name, entry);
  write_file_atomic(out, db.dump());
  std::cout << "\nwrote " << out << "\n";
  return 0;
}

stylerf::cli::Register reg("tune", run_tune);
}  // namespace
