// Device choice: the preference order, the name override and the error that lists devices.
#include <gtest/gtest.h>

#include "renderer/device_info.h"

namespace tessera {
namespace {

const std::vector<DeviceCandidate> kMachine = {
    {"llvmpipe (LLVM 15.0.6, 256 bits)", "cpu", true},
    {"Intel(R) UHD Graphics 770", "integrated", true},
    {"NVIDIA H200", "discrete", true},
    {"Old GPU without Vulkan 1.3", "discrete", false},
};

TEST(DeviceChoice, PrefersDiscreteThenIntegratedThenCpu) {
  EXPECT_EQ(*ChooseDevice(kMachine, ""), 2u);
  std::vector<DeviceCandidate> no_discrete = {kMachine[0], kMachine[1], kMachine[3]};
  EXPECT_EQ(*ChooseDevice(no_discrete, ""), 1u);
  std::vector<DeviceCandidate> cpu_only = {kMachine[3], kMachine[0]};
  EXPECT_EQ(*ChooseDevice(cpu_only, ""), 1u);
}

TEST(DeviceChoice, NameOverridesTheOrderCaseInsensitively) {
  EXPECT_EQ(*ChooseDevice(kMachine, "LLVMPIPE"), 0u);
  EXPECT_EQ(*ChooseDevice(kMachine, "uhd"), 1u);
}

TEST(DeviceChoice, UnusableDevicesAreNeverChosen) {
  absl::StatusOr<size_t> r = ChooseDevice(kMachine, "Old GPU");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound);
}

TEST(DeviceChoice, ErrorListsEveryDevice) {
  absl::StatusOr<size_t> r = ChooseDevice(kMachine, "radeon");
  ASSERT_FALSE(r.ok());
  const std::string msg(r.status().message());
  EXPECT_NE(msg.find("'radeon'"), std::string::npos) << msg;
  for (const DeviceCandidate& d : kMachine) EXPECT_NE(msg.find(d.name), std::string::npos) << msg;
  EXPECT_NE(msg.find("not usable"), std::string::npos) << msg;
  EXPECT_FALSE(ChooseDevice({}, "").ok());
}

}  // namespace
}  // namespace tessera
