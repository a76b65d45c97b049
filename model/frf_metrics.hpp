// FRF validation metrics of the delta paper (delta-lpv-receptance-coupling.txt, Sect. IV-C):
//   mu_err = (1/n) sum_f |M_f - P_f| / |M_f| * 100,   mu_acc = 100 - mu_err          (Eq. 70-71)
//   % error reduction = (mu_err,B - mu_err,P) / mu_err,B * 100                        (Eq. 72)
// M: measured, P: predicted, B: a fixed baseline model (e.g. the centre FRF used everywhere).
// The paper reports magnitude and phase separately (Tables II-III); the quantity compared is:
//   Magnitude: |M_f| vs |P_f|.
//   Phase:     phase of M (unwrapped along frequency) vs phase of P; the numerator is the phase
//              difference wrapped to (-180, 180] deg, the denominator |unwrapped phase of M|.
//              (The paper does not say how it treats wrapping; this choice is in docs/model.md.)
//   ComplexValue: |M_f - P_f| / |M_f| with the complex values, Eq. 71 read literally.
// Points whose denominator is zero are skipped; an error if none is left. mu_acc can be negative
// when the prediction is off by more than 100 % on average.
#pragma once

#include <complex>
#include <span>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/frf_set.hpp"

namespace feedloop::model {

enum class FrfQuantity { Magnitude, Phase, ComplexValue };

const char* to_string(FrfQuantity q);

// Eq. 71 (error part), in percent. measured and predicted must have the same length (> 0).
Result<double> mu_err(std::span<const std::complex<double>> measured,
                      std::span<const std::complex<double>> predicted, FrfQuantity q);
// Eq. 70-71, in percent.
Result<double> mu_acc(std::span<const std::complex<double>> measured,
                      std::span<const std::complex<double>> predicted, FrfQuantity q);
// Eq. 72, in percent. Error if the baseline is perfect (mu_err,B = 0).
Result<double> error_reduction_pct(std::span<const std::complex<double>> measured,
                                   std::span<const std::complex<double>> predicted,
                                   std::span<const std::complex<double>> baseline, FrfQuantity q);

// Per entry (i, j) of 3x3 FRF sets on the same grid (Table II rows are the diagonal).
Result<Eigen::Matrix3d> mu_acc(const FrfSet& measured, const FrfSet& predicted, FrfQuantity q);
// Per entry, Eq. 72 (Table III).
Result<Eigen::Matrix3d> error_reduction_pct(const FrfSet& measured, const FrfSet& predicted,
                                            const FrfSet& baseline, FrfQuantity q);

}  // namespace feedloop::model
