#pragma once
/// Interval scales fitted to a coverage instead of a likelihood (split conformal calibration):
/// on labelled strikes of a family harder than the training's, the scales that make the
/// `level` central intervals of z and theta hold exactly that share of the strikes. A Gaussian
/// likelihood fit of the z scale (the rms of the standardized errors) gives the right coverage
/// only when the errors are Gaussian; off the training distribution they are heavy-tailed, and
/// the rms answers to the few far misses instead of the level asked for.

#include <vector>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

/// The scales (relative to the predictions' own) under which `level` (in (0, 1)) of the labelled
/// records with a predictive distribution fall inside their central `level` intervals: sigma_z x
/// the level-quantile of |z - z_hat| / sigma_z over GaussianIntervalHalfWidth(level); kappa x the
/// c at which the share of records whose angle error lies within the central interval of
/// concentration c kappa is `level` (that share falls as c grows: bisection on log c). Scales stay
/// within UncertaintyCalibration's bounds; records without a distribution or labels are skipped;
/// none leaves 1 and 1. SchemaError when the counts differ.
UncertaintyCalibration FitCoverageCalibration(const std::vector<Prediction>& predictions,
                                              const FeatureSet& truth, double level = 0.9);

}  // namespace sonicboom::learning
