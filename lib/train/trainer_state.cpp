#include "lib/train/trainer_state.hpp"

#include "host/error.hpp"

namespace stylerf::train {

void read_trainer_state(const io::Checkpoint& ck, const std::string& what,
                        const std::function<void(const nlohmann::json& state)>& read) {
  try {
    read(ck.meta.at("trainer"));
  } catch (const nlohmann::json::exception& e) {
    throw host::Error("checkpoint " + ck.path + ": no " + what + " state to resume from (" + e.what() + ")");
  }
}

}  // namespace stylerf::train
