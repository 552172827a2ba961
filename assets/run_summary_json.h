#pragma once
/// @file
/// A run's measures (sim::RunSummary, sim_core/scene/garment_metrics.h) as one JSON object,
/// the line `costume_sim --json` ends with and `tools/garment_bench` prints per case. Field
/// names and units: docs/benchmarks.md ("The garment measures").

#include <string>

#include "sim_core/scene/garment_metrics.h"

namespace costume::assets {

/// The summary as a one-line JSON object (keys in the order of RunSummary; strains as
/// fractions, depths in mm, times in ms; a measure that was not taken is null, with the
/// reason in `penetration_unmeasured`).
std::string RunSummaryJson(const sim::RunSummary& summary);

}  // namespace costume::assets
