#pragma once
/// Small summaries of measured values shared by the experiments (sonicboom::Median is core's).

#include "sonicboom/core/statistics.h"
