// CiA 402 statusword decode / controlword encode exactly as SPEC §6.
#include <gtest/gtest.h>

#include "safestate/core/cia402.hpp"

using namespace safestate::core::cia402;

TEST(Cia402, DecodesEachStateOfTheSpecTable) {
  EXPECT_EQ(decode(0x0000), DriveState::NotReadyToSwitchOn);
  EXPECT_EQ(decode(0x0040), DriveState::SwitchOnDisabled);
  EXPECT_EQ(decode(0x0021), DriveState::ReadyToSwitchOn);
  EXPECT_EQ(decode(0x0023), DriveState::SwitchedOn);
  EXPECT_EQ(decode(0x0027), DriveState::OperationEnabled);
  EXPECT_EQ(decode(0x0007), DriveState::QuickStopActive);
  EXPECT_EQ(decode(0x000F), DriveState::FaultReactionActive);
  EXPECT_EQ(decode(0x0008), DriveState::Fault);
}

TEST(Cia402, IgnoresBitsOutsideTheMask) {
  // Bits 4 (voltage enabled), 7 (warning), 8..15 (manufacturer / target reached ...)
  EXPECT_EQ(decode(0x0237), DriveState::OperationEnabled);  // 0x0237 & 0x6F == 0x27
  EXPECT_EQ(decode(0xFF90 | 0x0027), DriveState::OperationEnabled);
  EXPECT_EQ(decode(0x1650), DriveState::SwitchOnDisabled);   // & 0x4F == 0x40
  EXPECT_EQ(decode(0x0088), DriveState::Fault);
}

TEST(Cia402, AStatuswordMatchingNoRowIsUnknownAndAFault) {
  EXPECT_EQ(decode(0x004F), DriveState::Unknown);
  EXPECT_EQ(decode(0x0001), DriveState::Unknown);
  EXPECT_EQ(decode(0x0061), DriveState::Unknown);  // switch-on-disabled bit with ready bits
  EXPECT_TRUE(is_fault(DriveState::Unknown));
  EXPECT_TRUE(is_fault(DriveState::Fault));
  EXPECT_TRUE(is_fault(DriveState::FaultReactionActive));
  EXPECT_FALSE(is_fault(DriveState::QuickStopActive));
  EXPECT_FALSE(is_fault(DriveState::OperationEnabled));
}

TEST(Cia402, PatternsAreMutuallyExclusiveOverAllStatuswords) {
  int unknown = 0;
  for (unsigned sw = 0; sw <= 0xFFFF; ++sw) {
    int matches = 0;
    for (const StatusPattern& p : kStatusPatterns) {
      matches += ((sw & p.mask) == p.value) ? 1 : 0;
    }
    ASSERT_LE(matches, 1) << std::hex << sw;
    unknown += (matches == 0) ? 1 : 0;
    ASSERT_EQ(decode(static_cast<std::uint16_t>(sw)) == DriveState::Unknown, matches == 0);
  }
  EXPECT_GT(unknown, 0);
}

TEST(Cia402, CanonicalStatuswordsRoundTrip) {
  for (const StatusPattern& p : kStatusPatterns) {
    EXPECT_EQ(decode(statusword_of(p.state)), p.state) << p.name;
  }
  EXPECT_EQ(decode(statusword_of(DriveState::Unknown)), DriveState::Unknown);
}

TEST(Cia402, ControlwordsAreThoseOfTheSpec) {
  EXPECT_EQ(cw::kShutdown, 0x0006);
  EXPECT_EQ(cw::kSwitchOn, 0x0007);
  EXPECT_EQ(cw::kEnableOperation, 0x000F);
  EXPECT_EQ(cw::kDisableVoltage, 0x0000);
  EXPECT_EQ(cw::kQuickStop, 0x0002);
  EXPECT_EQ(cw::kDisableOperation, 0x0007);
  EXPECT_EQ(cw::kFaultReset, 0x0080);
}

TEST(Cia402, NamesAreThoseOfTheStandard) {
  EXPECT_STREQ(to_string(DriveState::OperationEnabled), "Operation enabled");
  EXPECT_STREQ(to_string(DriveState::Unknown), "Unknown");
}
