// Benchmark parts for path following, written as sliced G-code (one external-perimeter loop per
// layer, layers 0.4 mm apart joined by a vertical move at the start point).
//
// fin (default), after the paper's test model (output-maneuvering-cartesian Sect. IV-B, Fig. 5/6:
// triangle-shaped, round curves of varying curvature, two 90-degree turns at the left end):
//   (0,0) -> (0,-4)                           down the flat left end; 90-degree turn
//   cubic Bezier (0,-4) (25,-4) (55,-30) (80,0) in 24 chords: round, with an inflection
//   (80,0)                                    a sharp tip (85-degree turn)
//   the mirror image back to (0,4)            90-degree turn, then down to (0,0)
// about 180 mm per layer: sharp corners sit between short segments, as slicer output of curved
// parts has them.
// star: straight edges into sharp corners (the case the paper's caveat Sect. V-A is about):
//   (6,0) -> (0,0) (90 deg) -> (0,40) with the corner at (0,40) rounded by r = 1.5 mm in 4 short
//   0.59 mm chords (22.5 deg each) -> (40,40) -> half ellipse centre (40,20), 25 x 20 mm, in
//   6-degree steps -> (40,0) -> (28,0) -> star tip (20,10) -> (12,0) -> (6,0); about 200 mm.
#pragma once

#include <string>

namespace feedloop::maneuver {

enum class TestPart { fin, star };

struct TestPartOptions {
  TestPart part = TestPart::fin;
  int layers = 10;
  double layer_height_mm = 0.4;
  double origin_x_mm = 90.0;
  double origin_y_mm = 90.0;
  // > 0: the outline scaled (about its first point) to this length per layer, e.g. 242 mm, the
  // paper's layer (Table III: 2.42 s at 0.1 m/s).
  double layer_length_mm = 0.0;
};

// The length of one layer's outline, mm (before any scaling).
double test_part_layer_length_mm(TestPart part);

std::string test_part_gcode(const TestPartOptions& options = {});

}  // namespace feedloop::maneuver
