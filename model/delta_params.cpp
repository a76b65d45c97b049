// Validation of the delta model parameters (see delta_params.hpp).
#include "model/delta_params.hpp"

#include <cmath>  // std::isfinite
#include <string>

namespace feedloop::model {

Status validate(const DeltaParams& p) {
  struct Field {
    const char* name;
    double value;
    double min;
    bool strict;
  };
  const Field fields[] = {
      {"m_c_kg", p.m_c_kg, 0.0, true},        {"m_f_kg", p.m_f_kg, 0.0, false},
      {"c_n_s_m", p.c_n_s_m, 0.0, false},     {"b_n_s_m", p.b_n_s_m, 0.0, false},
      {"k_n_m", p.k_n_m, 0.0, true},          {"d0_per_s2", p.d0_per_s2, 0.0, true},
      {"d2_per_s", p.d2_per_s, 0.0, true},    {"m1_kg", p.m1_kg, 0.0, true},
      {"m2_kg", p.m2_kg, 0.0, false},         {"b_x_n_s_m", p.b_x_n_s_m, 0.0, false},
      {"b_y_n_s_m", p.b_y_n_s_m, 0.0, false}, {"b_z_n_s_m", p.b_z_n_s_m, 0.0, false},
      {"k_x_n_m", p.k_x_n_m, 0.0, true},      {"k_y_n_m", p.k_y_n_m, 0.0, true},
      {"k_z_n_m", p.k_z_n_m, 0.0, true},      {"D_e_mm", p.D_e_mm, 0.0, true},
  };
  for (const Field& f : fields) {
    if (!std::isfinite(f.value)) return Error{std::string("delta parameter ") + f.name + " is not finite", {}};
    if (f.strict ? !(f.value > f.min) : !(f.value >= f.min))
      return Error{std::string("delta parameter ") + f.name + " must be " + (f.strict ? "> 0" : ">= 0") +
                       ", got " + std::to_string(f.value),
                   {}};
  }
  const double any[] = {p.d1_per_s, p.delta_x_mm, p.delta_y_mm, p.delta_z_mm};
  for (double v : any)
    if (!std::isfinite(v)) return Error{"delta parameter d1 or delta_* is not finite", {}};
  return validate(p.geometry);
}

}  // namespace feedloop::model
