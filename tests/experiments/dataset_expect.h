#pragma once
// Shared by the experiments suites: a short-record config and a bit-for-bit dataset comparison.

#include <gtest/gtest.h>

#include <string>

#include "sonicboom/core/config_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/experiments/config.h"

namespace sonicboom::experiments {

// The defaults with 0.6 s records (onset at 0.25 s) and seed 11: seconds per dozen strikes.
inline SonicBoomConfig ShortConfig() {
  ConfigSources sources;
  sources.overrides = {"audio.record_duration_s=0.6", "audio.onset_time_s=0.25", "seed=11"};
  return ResolveConfig(sources);
}

inline void ExpectSameSamples(const std::string& a_path, const std::string& b_path) {
  DatasetReader a(a_path), b(b_path);
  ASSERT_EQ(a.size(), b.size());
  for (int64_t i = 0; i < a.size(); ++i) {
    const StrikeSample sa = a.Read(i), sb = b.Read(i);
    EXPECT_EQ(sa.index, sb.index);
    EXPECT_EQ(sa.seed, sb.seed);
    EXPECT_EQ(sa.label.z_m, sb.label.z_m);
    EXPECT_EQ(sa.label.theta_rad, sb.label.theta_rad);
    EXPECT_TRUE(sa.audio.isApprox(sb.audio, 0.0f)) << "sample " << i;
    EXPECT_TRUE(sa.proprio.isApprox(sb.proprio, 0.0f));
    // every contact episode, bit for bit
    ASSERT_EQ(sa.contacts.size(), sb.contacts.size());
    for (size_t k = 0; k < sa.contacts.size(); ++k) {
      EXPECT_EQ(sa.contacts[k].time_s, sb.contacts[k].time_s);
      EXPECT_EQ(sa.contacts[k].impulse_Ns, sb.contacts[k].impulse_Ns);
      EXPECT_EQ(sa.contacts[k].point_m, sb.contacts[k].point_m);
      EXPECT_EQ(sa.contacts[k].kind, sb.contacts[k].kind);
    }
  }
}

}  // namespace sonicboom::experiments
