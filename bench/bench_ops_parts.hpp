// The op families of `stylerf bench ops`, one file each (bench/bench_ops_<family>.cpp).
#pragma once
#include "bench/bench.hpp"

namespace stylerf::bench {

void bench_ops_spatial(const BenchOptions& opt);  // bench/bench_ops_spatial.cpp: relu, pool, upsample, im2col, col2im
void bench_ops_norm(const BenchOptions& opt);     // bench/bench_ops_norm.cpp: stats, instance norm, AdaIN, losses
void bench_ops_layout(const BenchOptions& opt);   // bench/bench_ops_layout.cpp: rows <-> image, nn::linear
void bench_ops_style(const BenchOptions& opt);    // bench/bench_ops_style.cpp: SICT and DST kernels
void bench_ops_eval(const BenchOptions& opt);     // bench/bench_ops_eval.cpp: LPIPS distance map, LPIPS per pair
void bench_ops_shell(const BenchOptions& opt);    // bench/bench_ops_shell.cpp: the background shell's kernels

}  // namespace stylerf::bench
