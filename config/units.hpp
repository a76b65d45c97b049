// Physical units in config values. A number in the config may carry a unit ("3000 mm/s^2",
// "5 um", "38 g*cm^2"); the key's name suffix (max_accel_mm_s2, width_um, ...) fixes the unit the
// program uses, and a written unit must have the same dimension (it is then converted). A unit of
// another dimension is an error, so "300 mm/s" for an acceleration never loads silently.
//
// Dimensions are exponent vectors over (mass, length, time, current, angle, data). Angle is its
// own base so that a frequency in Hz (cycles/s = 2*pi rad/s) converts from rad/s correctly, while
// a bare "1/s" cannot be mistaken for Hz.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>

namespace feedloop::config::units {

struct Dimension {
  std::array<int, 6> exp{};  // kg, m, s, A, rad, byte

  bool operator==(const Dimension&) const = default;
  bool dimensionless() const { return exp == std::array<int, 6>{}; }
};

// A unit: its dimension and the factor that converts a value in it to SI (m, kg, s, A, rad, B).
struct Unit {
  Dimension dim;
  double to_si = 1.0;
  std::string symbol;  // as written, for messages
};

// Parses a unit expression such as "mm/s^2", "N*s/m", "N-s/m", "kg*m^2", "1/s", "s^-1", "mm/s2",
// "g-cm^2", "kHz", "rad/s", "mm/min", "µm". Returns nullopt when the text is not a unit.
std::optional<Unit> parse_unit(std::string_view text);

// The unit implied by a config key's suffix (longest suffix wins: steps_per_mm is 1/mm, not mm).
// nullopt for keys without a unit suffix (dimensionless numbers, counts).
std::optional<Unit> unit_for_key(std::string_view key);

// Human name of a dimension ("acceleration", "length", ...) or an exponent list.
std::string dimension_name(const Dimension& dim);

}  // namespace feedloop::config::units
