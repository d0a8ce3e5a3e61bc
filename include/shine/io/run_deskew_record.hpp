// How a `shine map` run deskewed its scans, as its stats.json records it ("deskew"), read back so
// that its held-out scans can be scored again as the run scored them (`shine eval --heldout
// --run`, cli/mapped_run.hpp):
//
//   "deskew": {"active": true, "scan_period_s": 0.1,
//              "point_time": {"field": "azimuth", ...},
//              "sweep": {"direction": "clockwise", "start_azimuth_deg": 180,
//                        "pose_azimuth_deg": 0, "period_s": 0.1}, ...}
//
// "sweep" is written where the scans were timed from their azimuth (io/sweep_times.hpp); the
// other fields are the run's deskew settings and what it did.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "shine/io/sweep_times.hpp"

namespace shine {

/// What read_run_deskew_record() finds.
struct RunDeskewRecord {
    bool active = false;         ///< the run deskewed its scans
    double scan_period_s = 0.1;  ///< seconds between scans of a sequence without stamps
    /// The scans without a time field were timed from their azimuth by this model.
    std::optional<SweepTimeModel> sweep;
};

/// The "sweep" object of a stats.json for `model`, as JSON text.
std::string sweep_record_json(const SweepTimeModel& model);

/// Parses a stats.json text. No "deskew" object, or "active" false: not deskewed. Throws
/// DataError naming `source` for text that is not a JSON object, fields of the wrong type, a
/// period that is not positive and finite, an incomplete or invalid "sweep", or an azimuth
/// timing without one (a stats.json written before the sweep was recorded).
RunDeskewRecord read_run_deskew_record(std::string_view stats_json, const std::string& source);

}  // namespace shine
