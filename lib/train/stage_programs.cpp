#include "lib/train/stage_programs.hpp"

#include <chrono>
#include <iomanip>
#include <ostream>

#include "host/gemm.hpp"
#include "lib/features/feature_targets.hpp"
#include "lib/field/vm_grid.hpp"
#include "lib/nn/conv_algo.hpp"
#include "lib/nn/reduce_path.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/style/sict.hpp"

namespace stylerf::train {

using host::ProgramBuild;

namespace {

// Rendering a field over a density geometry and training it: marching, compositing, the grids' kernels
// for the geometry's density grid and for the field's own grid, the loss and Adam.
std::vector<ProgramBuild> field_programs(const model::Geometry& geo, const field::VMGrid& values) {
  const std::string density = field::rank_build_options(geo.density.rank);
  std::vector<ProgramBuild> out = {{"render", ""},
                                   {"grid+render+march_density", density},
                                   {"composite", ""},
                                   {"grid", ""},
                                   {"grid", density},
                                   {"grid", field::rank_build_options(values.rank)},
                                   {"loss", ""},
                                   {"reduce", ""},
                                   {"elementwise", ""},
                                   {"optim", ""}};
  for (const std::string& o : render::composite_value_build_options()) out.push_back({"composite", o});
  // The device-dependent paths: work-group reductions, split-K GEMMs (the head's weight gradients, K =
  // samples) and the fixed-point scatter, each where it runs.
  if (nn::detail::use_group_reductions()) out.push_back({nn::detail::kGroupReduceProgram, ""});
  if (host::gemm_split_k_parts(64, 64, 1 << 20) >= 2) out.push_back({"gemm_split", ""});
  if (field::resolved_scatter_mode(field::ScatterMode::Auto) == field::ScatterMode::Fixed) {
    out.push_back({"grid+grid_fixed", density});
    out.push_back({"grid+grid_fixed", field::rank_build_options(values.rank)});
  }
  return out;
}

}  // namespace

std::vector<ProgramBuild> density_stage_programs(const model::DensityModel& m) {
  return field_programs(m.geo, m.rgb.app());
}

std::vector<ProgramBuild> feature_stage_programs(const model::FeatureModel& m) {
  // Beyond the field: VGG and the decoder (convolutions, norms, layouts) and the stage-2 targets.
  std::vector<ProgramBuild> out = field_programs(m.geo, m.field.head.grid());
  for (const char* p : {"nn", "layout", "linear"}) out.push_back({p, ""});
  out.push_back({"targets", features::kTargetDType == host::DType::F16 ? "-DTARGETS_F16" : ""});
  for (const std::string& o : nn::winograd_build_variants()) out.push_back({"winograd", o});
  return out;
}

std::vector<ProgramBuild> style_stage_programs(const model::StyleModel& m) {
  // Beyond stage 2's: SICT, DST, AdaIN's norms and the style losses' column statistics.
  std::vector<ProgramBuild> out = feature_stage_programs(m.features);
  out.push_back({"sict", style::sict_build_options()});
  for (const char* p : {"dst", "norm", "columns"}) out.push_back({p, ""});
  return out;
}

void build_stage_programs(const std::vector<ProgramBuild>& programs, std::ostream* log) {
  const auto t0 = std::chrono::steady_clock::now();
  host::Runtime& rt = host::Runtime::instance();
  for (const ProgramBuild& p : programs) rt.build(p);
  if (log)
    *log << "kernels built in " << std::fixed << std::setprecision(1)
         << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s ("
         << programs.size() << " programs; the time budget starts after them)" << std::endl;
}

}  // namespace stylerf::train
