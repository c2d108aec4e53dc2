#pragma once
/// Densities of the predictive distribution (torch-free): negative log-likelihoods used by the
/// metrics and the calibration, and the exponentially scaled Bessel functions behind them.

namespace sonicboom::learning::internal {

/// exp(-x) I0(x) and exp(-x) I1(x) for x >= 0: power series below 100, the asymptotic
/// (Hankel) series above; relative error near 1e-15.
double BesselI0Scaled(double x);
double BesselI1Scaled(double x);

/// I1(kappa) / I0(kappa), the mean resultant length of a von Mises distribution.
double VonMisesMeanResultant(double kappa);

/// -log of the normal density of `error` with standard deviation `std` (same unit).
double GaussianNll(double error, double std);
/// -log of the von Mises density (per radian) of an angle `angle_error` from the mean.
double VonMisesNll(double angle_error, double kappa);

}  // namespace sonicboom::learning::internal
