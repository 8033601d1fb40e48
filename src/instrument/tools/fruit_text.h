#pragma once
// Text and JSON renderings of pipeline results for the command-line tools.
#include <fruit_shape_completion/fruit_shape_pipeline.h>

#include <nlohmann/json.hpp>

#include <ostream>
#include <string>
#include <vector>

namespace fruit_shape_completion {

// One fruit as a JSON object (the fit_cloud --json schema; non-finite numbers become null).
nlohmann::json fruitJson(const FruitEstimate& f);

// A human-readable table of fruits.
void printFruitTable(std::ostream& os, const std::vector<FruitEstimate>& fruits);

}  // namespace fruit_shape_completion
