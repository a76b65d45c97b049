// Plot images for the identification report, drawn by gnuplot (Debian: gnuplot-nox) from data
// files that the report writes beside them. gnuplot is optional: without it the data files and a
// note are all the report gets (never a failure of `ident fit`).
//
// The executable is `gnuplot` on PATH, or the FEEDLOOP_GNUPLOT environment variable when set
// (an empty or missing program there means "no gnuplot": the tests use that to check the note).
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"

namespace feedloop::ident {

// The gnuplot program to run, or "" when none is usable (checked by running `PROGRAM --version`).
std::string find_gnuplot();

// One image: `script_body` is gnuplot commands after the terminal/output preamble (it refers to
// data files by absolute path; use gnuplot_quote()). Drawn to dir/<name>.png, script kept as
// dir/<name>.gp.
struct PlotSpec {
  std::string name;         // file stem, e.g. "bode"
  std::string title;        // what it shows (for report.md)
  int width_px = 1000, height_px = 700;
  std::string script_body;
};

struct PlotOutcome {
  std::vector<std::string> drawn;        // image file names (relative to dir) that exist now
  std::vector<std::string> drawn_titles;
  std::string note;                      // why some or all were not drawn; "" when all were
};

// Writes every script and runs gnuplot on each (without a shell). Never fails: problems are in note.
PlotOutcome draw_plots(const std::string& dir, const std::vector<PlotSpec>& plots);

// A string literal for gnuplot: single-quoted, quotes doubled.
std::string gnuplot_quote(const std::string& s);

}  // namespace feedloop::ident
