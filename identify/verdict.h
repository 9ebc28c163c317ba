// The verdict of a finished fit (identify/ internal; the rules are in identify/fit.h).
#pragma once

#include <vector>

#include "identify/fit.h"
#include "identify/fit_model.h"
#include "identify/multistart.h"
#include "identify/record_noise.h"

namespace millkit::identify {

// Sets result->summary.verdict and adds the reasons to its warnings. `noise` is per block;
// `best` indexes `minima`; result->parameters and channels are filled.
void JudgeFit(const FitModel& model, const std::vector<ChannelNoise>& noise,
              const std::vector<LocalFit>& minima, int best, const FitOptions& options,
              FitResult* result);

}  // namespace millkit::identify
