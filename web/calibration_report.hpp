// The last calibration report for feedloop's page: the newest `report.json` that
// `feedloop ident fit --out DIR` wrote (docs/ident.md; the contract in DESIGN.md), looked for in
// web.calibration_dir itself and one level down, with the `report.md` beside it. Read when asked
// (the I/O thread; a report is a few KiB): not a timing path.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace feedloop::web {

// {"found": true, "path", "modified" (Unix s), "report" (report.json), "markdown" (report.md or
// ""), "dir"} or {"found": false, "dir", "message"} (no report yet, or why it could not be read:
// a report.json that is not JSON is named with the parser's message and byte).
nlohmann::json latest_calibration_report(const std::string& dir);

}  // namespace feedloop::web
