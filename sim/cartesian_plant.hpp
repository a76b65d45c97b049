// A Cartesian machine for the mock transport: one independent GantryAxis per axis (the thesis's
// IMC architecture: one MCU per axis). Axes do not couple dynamically (the thesis models X and Y
// separately; the Y preset's m2 = 1.07 kg already includes the X gantry it carries).
#pragma once

#include <array>
#include <string>

#include "core/result.hpp"
#include "sim/gantry_axis.hpp"

namespace feedloop::sim {

struct CartesianPlantParams {
  // Default: thesis X and Y, and an X-type axis for Z.
  std::array<GantryAxisParams, 3> axes{thesis_x_axis(), thesis_y_axis(), thesis_x_axis()};
};

class CartesianPlant {
 public:
  static Result<CartesianPlant> create(const CartesianPlantParams& p) {
    static const char* const kNames[3] = {"x", "y", "z"};
    std::array<GantryAxisParams, 3> ps = p.axes;
    for (size_t i = 0; i < 3; ++i) ps[i].seed += 1000 * i;  // independent encoder noise per axis
    auto x = GantryAxis::create(ps[0]);
    auto y = GantryAxis::create(ps[1]);
    auto z = GantryAxis::create(ps[2]);
    Result<GantryAxis>* rs[3] = {&x, &y, &z};
    for (size_t i = 0; i < 3; ++i)
      if (!rs[i]->ok()) return Error{std::string("axis ") + kNames[i] + ": " + rs[i]->error().message, {}};
    return CartesianPlant(std::move(x.value()), std::move(y.value()), std::move(z.value()));
  }

  // 0 = x, 1 = y, 2 = z. Each axis keeps its own time line (one MCU each).
  GantryAxis& axis(int i) { return axes_[static_cast<size_t>(i)]; }
  device::MotorPort& port(int i) { return axes_[static_cast<size_t>(i)]; }
  void advance_to(double t_s) {
    for (GantryAxis& a : axes_) a.advance_to(t_s);
  }

 private:
  CartesianPlant(GantryAxis x, GantryAxis y, GantryAxis z) : axes_{std::move(x), std::move(y), std::move(z)} {}
  std::array<GantryAxis, 3> axes_;
};

}  // namespace feedloop::sim
