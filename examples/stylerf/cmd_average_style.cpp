// stylerf average-style CKPT CKPT... -o OUT [--force]: the uniform average of the trained weights of style
// checkpoints of one run (snapshots from `train-style --snapshot-every N`), a model to stylise and
// evaluate with (lib/train/style_average.hpp says what is averaged and what must agree).
#include <boost/program_options.hpp>
#include <iostream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "host/error.hpp"
#include "lib/train/style_average.hpp"

namespace po = boost::program_options;

namespace {

int run_average_style(int argc, char** argv) {
  std::vector<std::string> inputs;
  std::string out, device;
  bool force = false;
  po::options_description desc("stylerf average-style CKPT CKPT... -o OUT [options]");
  desc.add_options()("help,h", "show this help")("ckpt", po::value(&inputs)->multitoken(),
                                                 "style checkpoints of one run (also positional)")(
      "output,o", po::value(&out), "the averaged style checkpoint (written atomically)")(
      "force", po::bool_switch(&force), "overwrite an existing file at -o")(
      "device", po::value(&device), "OpenCL device: index, cpu|gpu|accelerator, or part of a name");
  po::positional_options_description pos;
  pos.add("ckpt", -1);
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(desc).positional(pos).run(), vm);
  po::notify(vm);
  if (vm.count("help") || out.empty() || inputs.empty()) {
    std::cout << desc;
    return vm.count("help") ? 0 : 2;
  }
  if (inputs.size() < 2) throw stylerf::host::Error("average-style: needs two or more checkpoints to average");
  stylerf::cli::check_checkpoint_output(out, false, force);
  stylerf::cli::init_runtime(device, false);
  const stylerf::io::Checkpoint avg = stylerf::train::average_style_checkpoints(inputs);
  stylerf::io::save_checkpoint(out, avg);
  std::cout << "averaged " << inputs.size() << " style checkpoints (iterations";
  for (const auto& f : avg.meta.at("averaged").at("from")) std::cout << " " << f.at("iteration").get<int>();
  std::cout << ") into " << out << std::endl;
  return 0;
}

stylerf::cli::Register reg("average-style", "uniform average of style checkpoints of one run (snapshots)",
                           run_average_style);
}  // namespace
