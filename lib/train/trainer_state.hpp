// Resuming a trainer: its state in a checkpoint's meta["trainer"], read with the error every stage gives.
#pragma once
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "lib/io/checkpoint.hpp"

namespace stylerf::train {

// Calls `read` on ck.meta["trainer"]; a missing or mistyped field becomes an Error naming the checkpoint's
// file and `what` ("trainer", "style-trainer"), not a bare JSON exception.
void read_trainer_state(const io::Checkpoint& ck, const std::string& what,
                        const std::function<void(const nlohmann::json& state)>& read);

}  // namespace stylerf::train
