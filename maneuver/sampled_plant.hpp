// A plant as a sampled servo sees it: what it measures at a sample, the voltages held over one
// period, and where the nozzle really is. The simulation (simulation.hpp) runs the maneuvering
// servo against either the controller's own model (NominalSampledPlant: Table I, measured
// exactly) or a plant that is not its model (offnominal_plant.hpp).
#pragma once

#include "maneuver/printer_model.hpp"

namespace feedloop::maneuver {

class SampledPlant {
 public:
  virtual ~SampledPlant() = default;
  virtual void reset(const Vec3& at_m) = 0;  // at rest with the nozzle at at_m
  virtual PlantState measure() const = 0;    // what the servo reads at this sample
  virtual void advance(const Vec3& w_v, double period_s) = 0;  // w held over the period
  virtual Vec3 nozzle_m() const = 0;                           // the true nozzle position
  virtual Vec3 nozzle_velocity_m_s() const = 0;
  virtual bool limited() const { return false; }  // a drive limit acted in the last advance
};

// The controller's own model: Eq. 19-20 with gravity, the state measured exactly, RK4 substeps
// of at most max_step_s.
class NominalSampledPlant final : public SampledPlant {
 public:
  NominalSampledPlant(const CartesianDcPlant& plant, double max_step_s)
      : plant_(plant), max_step_s_(max_step_s) {}
  void reset(const Vec3& at_m) override { x_ = PlantState{at_m, Vec3::Zero()}; }
  PlantState measure() const override { return x_; }
  void advance(const Vec3& w_v, double period_s) override;
  Vec3 nozzle_m() const override { return x_.x1_m; }
  Vec3 nozzle_velocity_m_s() const override { return x_.x2_m_s; }
  void set_state(const PlantState& x) { x_ = x; }

 private:
  const CartesianDcPlant& plant_;
  double max_step_s_;
  PlantState x_{};
};

}  // namespace feedloop::maneuver
