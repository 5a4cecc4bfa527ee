// The rendering commands under several MPI ranks (host/dist.hpp): each rank renders its share of the views
// into a folder of its own, and rank 0 gathers every file into the real output folder, so that the job
// writes exactly what one process writes. With one rank these are no-ops.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

namespace stylerf::cli {

// Whether view i (of the command's list) is this rank's: views are dealt round robin. Ask it as the rank
// reaches each view: it is the rank's sign of life to the others (host::Dist::alive).
bool my_view(size_t i);
// Where this rank writes: `out` on rank 0, a fresh temporary folder on the others.
std::string rank_output_dir(const std::string& out);
// Collective. Rank 0 writes every other rank's files (their paths relative to their folder kept) under `out`,
// each atomically; the other ranks remove their folders.
void collect_rank_outputs(const std::string& rank_dir, const std::string& out);
// Collective. Every rank's per-view rows (a JSON array of objects with a "view") on rank 0, ordered by view
// as one process lists them; the other ranks get an empty array.
nlohmann::json gather_view_rows(const nlohmann::json& mine);

}  // namespace stylerf::cli
