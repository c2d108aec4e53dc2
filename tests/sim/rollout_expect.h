#pragma once
// Shared by the sim tests: two rollouts are the same to the bit (records, contacts, proprio).
#include <gtest/gtest.h>

#include "sonicboom/sim/rollout.h"

namespace sonicboom::sim {

inline void ExpectSameRecords(const RolloutResult& a, const RolloutResult& b) {
  ASSERT_EQ(a.valid, b.valid);
  EXPECT_EQ(a.invalid_reason, b.invalid_reason);
  EXPECT_EQ(a.object, b.object);
  EXPECT_EQ(a.motion, b.motion);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_TRUE(a.object_pose.matrix() == b.object_pose.matrix());
  ASSERT_EQ(a.contacts.size(), b.contacts.size());
  for (size_t i = 0; i < a.contacts.size(); ++i) {
    const ContactRecord &x = a.contacts[i], &y = b.contacts[i];
    EXPECT_EQ(x.time_s, y.time_s);
    EXPECT_EQ(x.duration_s, y.duration_s);
    EXPECT_EQ(x.point_world_m, y.point_world_m);
    EXPECT_EQ(x.point_m, y.point_m);
    EXPECT_EQ(x.normal, y.normal);
    EXPECT_EQ(x.normal_speed_m_s, y.normal_speed_m_s);
    EXPECT_EQ(x.effective_mass_kg, y.effective_mass_kg);
    EXPECT_EQ(x.impulse_Ns, y.impulse_Ns);
    EXPECT_EQ(x.peak_force_N, y.peak_force_N);
    EXPECT_EQ(x.kind, y.kind);
    EXPECT_EQ(x.object, y.object);
    EXPECT_EQ(x.segment, y.segment);
  }
  ASSERT_EQ(a.proprio.rows(), b.proprio.rows());
  EXPECT_TRUE((a.proprio.array() == b.proprio.array()).all());
  EXPECT_EQ(a.joint_speed_rad_s, b.joint_speed_rad_s);
}

}  // namespace sonicboom::sim
