// CiA 402 statusword decode / controlword encode exactly as SPEC §6.
#include <gtest/gtest.h>

#include "safestate/core/cia402.hpp"

using namespace safestate::core::cia402;

// @req CIA-DECODE
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

// @req CIA-DECODE
TEST(Cia402, IgnoresBitsOutsideTheMask) {
  // Bits 4 (voltage enabled), 7 (warning), 8..15 (manufacturer / target reached ...)
  EXPECT_EQ(decode(0x0237), DriveState::OperationEnabled);  // 0x0237 & 0x6F == 0x27
  EXPECT_EQ(decode(0xFF90 | 0x0027), DriveState::OperationEnabled);
  EXPECT_EQ(decode(0x1650), DriveState::SwitchOnDisabled);   // & 0x4F == 0x40
  EXPECT_EQ(decode(0x0088), DriveState::Fault);
}

// @req CIA-UNKNOWN
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

// @req CIA-DECODE
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

// @req CIA-DECODE
TEST(Cia402, TheLookupTableDecodesExactlyAsThePatternSearch) {
  for (unsigned sw = 0; sw <= 0xFFFF; ++sw) {
    ASSERT_EQ(decode(static_cast<std::uint16_t>(sw)), decode_by_search(static_cast<std::uint16_t>(sw))) << std::hex << sw;
  }
}

TEST(Cia402, CanonicalStatuswordsRoundTrip) {
  for (const StatusPattern& p : kStatusPatterns) {
    EXPECT_EQ(decode(statusword_of(p.state)), p.state) << p.name;
  }
  EXPECT_EQ(decode(statusword_of(DriveState::Unknown)), DriveState::Unknown);
}

// @req CIA-DECODE
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

// @req CIA-DECODE SIM-CELL
TEST(Cia402DeviceControl, EveryTransitionOfTheStateMachine) {
  using S = DriveState;
  const std::uint16_t none = 0x0000;
  struct Case {
    S from;
    std::uint16_t cw;
    bool power;
    S to;
    const char* transition;
  };
  const Case cases[] = {
      {S::NotReadyToSwitchOn, none, false, S::SwitchOnDisabled, "1"},
      {S::SwitchOnDisabled, cw::kShutdown, false, S::ReadyToSwitchOn, "2"},
      {S::SwitchOnDisabled, cw::kSwitchOn, true, S::SwitchOnDisabled, "2 needs Shutdown"},
      {S::ReadyToSwitchOn, cw::kSwitchOn, true, S::SwitchedOn, "3"},
      {S::ReadyToSwitchOn, cw::kSwitchOn, false, S::ReadyToSwitchOn, "3 needs the DC link"},
      {S::ReadyToSwitchOn, cw::kShutdown, true, S::ReadyToSwitchOn, "stay"},
      {S::ReadyToSwitchOn, cw::kDisableVoltage, true, S::SwitchOnDisabled, "7 disable voltage"},
      {S::ReadyToSwitchOn, cw::kQuickStop, true, S::SwitchOnDisabled, "7 quick stop"},
      {S::SwitchedOn, cw::kEnableOperation, true, S::OperationEnabled, "4"},
      {S::SwitchedOn, cw::kShutdown, true, S::ReadyToSwitchOn, "6"},
      {S::SwitchedOn, cw::kDisableVoltage, true, S::SwitchOnDisabled, "10 disable voltage"},
      {S::SwitchedOn, cw::kQuickStop, true, S::SwitchOnDisabled, "10 quick stop"},
      {S::SwitchedOn, cw::kSwitchOn, false, S::SwitchOnDisabled, "10 power lost"},
      {S::SwitchedOn, cw::kSwitchOn, true, S::SwitchedOn, "stay"},
      {S::OperationEnabled, cw::kDisableOperation, true, S::SwitchedOn, "5"},
      {S::OperationEnabled, cw::kShutdown, true, S::ReadyToSwitchOn, "8"},
      {S::OperationEnabled, cw::kDisableVoltage, true, S::SwitchOnDisabled, "9"},
      {S::OperationEnabled, cw::kEnableOperation, false, S::SwitchOnDisabled, "9 power lost"},
      {S::OperationEnabled, cw::kQuickStop, true, S::QuickStopActive, "11"},
      {S::OperationEnabled, cw::kEnableOperation, true, S::OperationEnabled, "stay"},
      {S::QuickStopActive, cw::kDisableVoltage, true, S::SwitchOnDisabled, "12"},
      {S::QuickStopActive, cw::kQuickStop, false, S::SwitchOnDisabled, "12 power lost"},
      {S::QuickStopActive, cw::kEnableOperation, true, S::OperationEnabled, "16"},
      {S::QuickStopActive, cw::kQuickStop, true, S::QuickStopActive, "stay"},
      {S::FaultReactionActive, none, true, S::Fault, "14"},
      {S::Unknown, none, true, S::Fault, "unknown is a fault"},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(next_state(c.from, 0x0000, c.cw, c.power), c.to) << "transition " << c.transition;
  }
}

// @req CIA-DECODE
TEST(Cia402DeviceControl, FaultIsLeftOnlyOnARisingEdgeOfBit7) {
  EXPECT_EQ(next_state(DriveState::Fault, 0x0000, cw::kFaultReset, false), DriveState::SwitchOnDisabled);
  EXPECT_EQ(next_state(DriveState::Fault, cw::kFaultReset, cw::kFaultReset, true), DriveState::Fault) << "held, no edge";
  EXPECT_EQ(next_state(DriveState::Fault, 0x0000, cw::kEnableOperation, true), DriveState::Fault);
  EXPECT_TRUE(fault_reset_edge(0x0000, 0x0080));
  EXPECT_FALSE(fault_reset_edge(0x0080, 0x0080));
}
