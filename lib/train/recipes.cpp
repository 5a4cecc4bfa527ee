#include "lib/train/recipes.hpp"

#include "host/error.hpp"

namespace stylerf::train {

Recipe parse_recipe(const std::string& name) {
  if (name == "fast") return Recipe::Fast;
  if (name == "paper") return Recipe::Paper;
  throw host::Error("recipe '" + name + "' is not one of: fast, paper");
}

const char* recipe_name(Recipe r) { return r == Recipe::Fast ? "fast" : "paper"; }

}  // namespace stylerf::train
