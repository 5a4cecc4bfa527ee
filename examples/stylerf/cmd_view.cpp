// stylerf view --ckpt STYLE_CKPT [--styles DIR] [--port N] [--host ADDR] [--open]: a live viewer in the
// browser. The page (embedded) orbits the scene, restyles it with any picture dropped on it (zero-shot),
// mixes two styles and composes them by a 3D region; previews while the camera moves, the full frame when it
// stops. API and safety rules: docs/viewer.md.
#include <httplib.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <boost/program_options.hpp>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <random>
#include <set>
#include <thread>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "examples/stylerf/refine_option.hpp"
#include "examples/stylerf/strength_option.hpp"
#include "examples/stylerf/view_request.hpp"
#include "examples/stylerf/view_server.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/style/style_image.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;
namespace cli = stylerf::cli;
namespace model = stylerf::model;
namespace viewer = stylerf::viewer;

struct ViewArgs {
  std::string ckpt, styles_dir, host = "127.0.0.1", scene_dir, device, supersample_text = "0";
  int port = 8765, chunk = 8192, max_upload_mb = 16;
  float refine_contrast = model::kRefineContrast, strength = cli::kCheckpointStrength;
  bool open = false, decoded_background = false;
};

int parse_view_args(int argc, char** argv, ViewArgs& a) {
  po::options_description desc("stylerf view --ckpt STYLE_CKPT [--styles DIR] [--port N] [--host ADDR] [--open]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&a.ckpt), "style checkpoint (train-style)")(
      "styles", po::value(&a.styles_dir), "a folder of style images offered beside the checkpoint's held-out styles")(
      "port", po::value(&a.port)->default_value(8765), "port to listen on (0: any free port, printed)")(
      "host", po::value(&a.host)->default_value("127.0.0.1"),
      "address to bind; any other than loopback requires the token printed at start on every request")(
      "open", po::bool_switch(&a.open), "open the page in the default browser (xdg-open)")(
      "scene", po::value(&a.scene_dir), "scene directory (default: the one the checkpoint was trained on)")(
      "max-upload-mb", po::value(&a.max_upload_mb)->default_value(16), "largest style image accepted, in MB")(
      "decoded-background", po::bool_switch(&a.decoded_background),
      "scenes with a background colour: keep the decoder's empty space instead of compositing over the colour")(
      "chunk", po::value(&a.chunk)->default_value(8192), "rays per renderer call (bounds memory)")(
      "supersample", cli::supersample_value(&a.supersample_text), cli::kSupersampleHelp)(
      "refine-contrast", cli::refine_contrast_value(&a.refine_contrast), cli::kRefineContrastHelp)(
      "strength", cli::strength_value(&a.strength), cli::kStrengthHelp)(
      "device", po::value(&a.device), cli::kDeviceHelp);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || a.ckpt.empty()) {
    cli::print_help(std::cout, "view", desc);
    return vm.count("help") ? 0 : 2;
  }
  if (a.port < 0 || a.port > 65535) throw Error("--port must be in [0, 65535]");
  if (a.chunk < 1) throw Error("--chunk must be >= 1");
  if (a.max_upload_mb < 1 || a.max_upload_mb > 1024) throw Error("--max-upload-mb must be in [1, 1024]");
  cli::supersample_from(a.supersample_text);
  cli::check_refine_contrast(a.refine_contrast);
  return -1;
}

bool is_loopback(const std::string& host) { return host == "127.0.0.1" || host == "localhost" || host == "::1"; }

std::string random_token() {
  std::random_device rd;
  std::ostringstream s;
  for (int i = 0; i < 4; ++i) s << std::hex << std::setw(8) << std::setfill('0') << rd();
  return s.str();
}

// The checkpoint's held-out styles (those whose files are here) and the images of --styles.
void add_styles(viewer::StyleLibrary& lib, const stylerf::io::Checkpoint& ck, const std::string& dir) {
  const auto holdout = ck.meta.value("styles", nlohmann::json::object()).value("holdout", nlohmann::json::array());
  int missing = 0;
  std::set<fs::path> added;  // a held-out style may sit in --styles too: offered once
  auto key = [](const std::string& path) {
    std::error_code ec;
    const fs::path p = fs::weakly_canonical(path, ec);
    return ec ? fs::path(path) : p;
  };
  for (const auto& p : holdout) {
    const std::string path = p.get<std::string>();
    try {
      lib.add_file(path, fs::path(path).stem().string(), "holdout");
      added.insert(key(path));
    } catch (const Error&) {
      ++missing;
    }
  }
  if (missing > 0) std::cout << missing << " held-out style image(s) of the checkpoint are not on this machine\n";
  if (!dir.empty()) {
    if (!fs::is_directory(dir)) throw Error("--styles " + dir + ": not a folder");
    for (const auto& f : stylerf::style::style_images_in(dir, &std::cout))
      if (added.insert(key(f)).second) lib.add_file(f, fs::path(f).stem().string(), "folder");
  }
  if (lib.list().empty())
    throw Error("no style image to show: the checkpoint's held-out styles are not here; give --styles DIR");
}

// Renders the page's first camera (training view 0, the first style) as preview and full frame, so that
// the kernels are built and both contents are cached before the first client comes.
void warm_up(viewer::FrameRenderer& r, const std::string& style_id) {
  viewer::FrameRequest f;
  f.style = style_id;
  f.side = std::max(cli::kMinSide, r.full_side() / 4);
  r.render(f);
  f.side = r.full_side();
  const viewer::Frame full = r.render(f);
  std::cout << "first full frame: " << std::fixed << std::setprecision(2) << full.render_s << " s\n";
}

// Ctrl-C and SIGTERM: the handler only writes a byte to a pipe (async-signal-safe; any thread may take the
// signal, including those libraries start before main), and a thread reading the pipe stops the server.
int g_stop_pipe[2] = {-1, -1};

extern "C" void on_stop_signal(int) {
  const char byte = 's';
  [[maybe_unused]] const ssize_t n = ::write(g_stop_pipe[1], &byte, 1);
}

void install_stop_signals() {
  if (::pipe(g_stop_pipe) != 0) throw Error("view: cannot make the pipe that signals stop");
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int serve(const ViewArgs& a, cli::ViewContext& ctx) {
  install_stop_signals();  // until here Ctrl-C ends the loading at once, as for any command
  httplib::Server server;
  // Threads for connections: a browser keeps several open per tab; renders queue in the scheduler.
  server.new_task_queue = [] { return new httplib::ThreadPool(32); };
  server.set_payload_max_length(ctx.max_upload_bytes);
  server.set_keep_alive_timeout(2);
  cli::install_view_routes(server, ctx);
  const int port = a.port == 0 ? server.bind_to_any_port(a.host) : (server.bind_to_port(a.host, a.port) ? a.port : -1);
  if (port < 0) throw Error("cannot listen on " + a.host + ":" + std::to_string(a.port) + " (in use? try --port 0)");
  std::string url = "http://" + (a.host.find(':') != std::string::npos ? "[" + a.host + "]" : a.host) + ":" +
                    std::to_string(port) + "/";
  if (!ctx.token.empty()) url += "?token=" + ctx.token;
  std::cout << "stylerf view: " << url << "\n(Ctrl-C stops it)" << std::endl;
  if (a.open && std::system(("xdg-open '" + url + "' >/dev/null 2>&1 &").c_str()) != 0)
    std::cout << "could not open a browser; open " << url << " yourself\n";
  std::atomic<bool> signalled{false}, listening{true};
  std::thread stopper([&] {
    char byte = 0;
    while (::read(g_stop_pipe[0], &byte, 1) < 0 && errno == EINTR) {
    }
    if (!listening) return;  // listen ended on its own and woke this thread
    signalled = true;
    while (listening && !server.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ctx.scheduler.stop();  // cancels the render in progress
    server.stop();
  });
  const bool ok = server.listen_after_bind();
  listening = false;
  if (!signalled) on_stop_signal(0);  // wake the stopper
  stopper.join();
  std::cout << "stylerf view: stopped (" << ctx.scheduler.completed() << " pieces of work, "
            << ctx.scheduler.superseded() << " superseded)" << std::endl;
  return ok || signalled ? 0 : 1;
}

int run_view(int argc, char** argv) {
  ViewArgs a;
  if (const int code = parse_view_args(argc, argv, a); code >= 0) return code;
  cli::init_runtime(a.device, false);
  auto ck = stylerf::io::load_checkpoint(a.ckpt, "");
  if (ck.kind != "style")
    throw Error("checkpoint " + a.ckpt + " holds a '" + ck.kind + "' stage, not a trained stylizer; train one with "
                "`stylerf train-style --features " + a.ckpt + "`");
  auto m = model::StyleModel::load(ck);
  cli::apply_strength(m, a.strength);
  stylerf::scene::SceneOverrides o;
  o.dir = a.scene_dir;
  o.load_images = false;  // cameras only
  const auto scene = stylerf::scene::open_scene_for(ck.meta.value("scene", nlohmann::json::object()), a.ckpt, o).scene;
  auto vgg = stylerf::nn::VggEncoder::load_default();
  stylerf::style::StyleEncoder encoder(m.dst, vgg, "");  // codes in memory: a viewer's styles are few
  viewer::FrameRendererOptions ro;
  ro.supersample = cli::supersample_from(a.supersample_text);
  ro.refine_contrast = a.refine_contrast;
  ro.chunk = a.chunk;
  ro.decoded_background = a.decoded_background;
  const model::SceneStyleStats stats(m, scene, model::SceneStyleStats::kDefaultViews,
                                     ro.supersample == 0 ? m.inference_supersample : ro.supersample, a.refine_contrast);
  const fs::path work = fs::temp_directory_path() / ("stylerf-view-" + std::to_string(::getpid()));
  viewer::StyleLibrary styles((work / "uploads").string());
  add_styles(styles, ck, a.styles_dir);
  viewer::FrameRenderer renderer(m, scene, styles, encoder, stats, ro);
  warm_up(renderer, styles.list().front().id);
  viewer::FairScheduler scheduler;
  cli::ViewContext ctx{scene, styles, renderer, scheduler, stylerf::host::Runtime::instance().device().name,
                       is_loopback(a.host) ? "" : random_token(), size_t(a.max_upload_mb) << 20, work.string()};
  const int rc = serve(a, ctx);
  std::error_code ec;
  fs::remove_all(work, ec);
  return rc;
}

cli::Register reg("view", run_view);
}  // namespace
