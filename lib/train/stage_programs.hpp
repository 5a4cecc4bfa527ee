// The OpenCL programs each training stage launches, with the build options it launches them with, so that
// its loop can build them all before its clock starts: on a cold kernel cache PoCL takes ~0.7 s a
// program, which would otherwise be spent inside the first steps and count against --minutes.
//
// Programs whose options come from a small fixed set (composite's vector width, Winograd's tile size)
// are listed with every option; those built for a grid's ranks, with the stage's grids. The stages'
// tests build a list, take steps of every kind (the density stage's events too) and check that no program
// was left to build. The own-GEMM and CLBlast engines (not the default on CPUs) still build at first use.
#pragma once
#include <iosfwd>
#include <vector>

#include "host/runtime.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/feature_model.hpp"
#include "lib/model/style_model.hpp"

namespace stylerf::train {

std::vector<host::ProgramBuild> density_stage_programs(const model::DensityModel& m);
std::vector<host::ProgramBuild> feature_stage_programs(const model::FeatureModel& m);
std::vector<host::ProgramBuild> style_stage_programs(const model::StyleModel& m);

// Builds them (those already built cost nothing) and, with a log, says how long that took.
void build_stage_programs(const std::vector<host::ProgramBuild>& programs, std::ostream* log);

}  // namespace stylerf::train
