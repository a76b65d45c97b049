// A compliant extruder: what comes out of the nozzle when the extruder motor turns. The plant has
// its own structure (not the inverse of the pressure advance's first-order model):
//
//   motor position e_m (steps x mm per step, mm of filament)
//     -> tube / drive play: a backlash element of total width b (the filament's lost motion in a
//        Bowden tube or the drive gear's play):  y = clamp(y, e_m - b/2, e_m + b/2)
//     -> filament spring (filament + tube + melt compressibility lumped, stiffness k_f):
//        F = k_f * (y - x_f), x_f the filament's position at the melt zone
//     -> melt chamber pressure p = max(F, 0) / A_f (the melt does not pull the filament back)
//     -> shear-thinning nozzle flow q = c * p^n  (c from one operating point: q_ref at F_ref;
//        n > 1: the flow grows faster than the pressure), which consumes filament:
//        dx_f/dt = q / A_f
//     -> melt-flow lag to the nozzle exit: dq_noz/dt = (q - q_noz) / tau_m
//   output: q_noz (mm^3/s) and its integral, the extruded volume.
//
// Linearised at a flow q0 the filament side is a first-order lag of time constant
// tau(q0) = A_f^2 p0 / (k_f n q0) (p0 = (q0/c)^(1/n)): it grows as the flow falls (q0^(1/n - 1)),
// so one pressure advance K (a constant tau) fits one flow only; the play and the melt lag are
// not first order at all. Defaults: a Bowden printer (docs/pressure_advance.md states the
// sources and the reasoning).
#pragma once

namespace feedloop::sim {

struct ExtruderPlantParams {
  double filament_diameter_mm = 1.75;
  double stiffness_n_per_mm = 15.0;  // k_f: ~500 mm of PLA (E ~ 3.5 GPa) in a Bowden tube
  double play_mm = 0.05;             // b: lost motion of the drive and the tube, total width
  double flow_ref_mm3_s = 10.0;      // q_ref: an operating point of the nozzle's flow law ...
  double force_ref_n = 20.0;         // ... F_ref: the filament force there
  double flow_exponent = 1.4;        // n in q = c p^n (shear-thinning melt)
  double melt_lag_s = 0.010;         // tau_m
};

class ExtruderPlant {
 public:
  explicit ExtruderPlant(const ExtruderPlantParams& p = {});
  // At rest, unloaded, the motor (and the filament) at e_m.
  void reset(double motor_mm);
  // Advances dt_s with the motor at motor_mm (held over the step). RT-safe.
  void step(double motor_mm, double dt_s);

  double nozzle_flow_mm3_s() const { return q_noz_mm3_s_; }
  double extruded_mm3() const { return volume_mm3_; }
  double filament_force_n() const { return force_n_; }
  double filament_area_mm2() const { return area_mm2_; }
  // tau(q0) of the linearised filament side at a steady flow q0 (see above).
  double time_constant_s(double flow_mm3_s) const;
  const ExtruderPlantParams& params() const { return p_; }

 private:
  double flow_for_force(double force_n) const;
  ExtruderPlantParams p_;
  double area_mm2_ = 0.0;
  double c_ = 0.0;  // q = c p^n, p in N/mm^2
  double play_out_mm_ = 0.0, filament_mm_ = 0.0;
  double force_n_ = 0.0, q_noz_mm3_s_ = 0.0, volume_mm3_ = 0.0;
};

}  // namespace feedloop::sim
