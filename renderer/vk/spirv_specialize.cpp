#include "renderer/vk/spirv_specialize.h"

#include <string>
#include <unordered_map>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "spirv-tools/optimizer.hpp"

namespace tessera::vk {

absl::StatusOr<std::vector<uint32_t>> SpecializeSpirv(std::span<const uint32_t> code,
                                                      std::span<const uint32_t> constants) {
  spvtools::Optimizer opt(SPV_ENV_VULKAN_1_3);
  std::string first_message;
  opt.SetMessageConsumer([&](spv_message_level_t level, const char*, const spv_position_t& at,
                             const char* message) {
    if (level <= SPV_MSG_ERROR && first_message.empty())
      first_message = absl::StrCat("word ", at.index, ": ", message);
  });
  std::unordered_map<uint32_t, std::vector<uint32_t>> values;
  for (uint32_t id = 0; id < constants.size(); ++id) values[id] = {constants[id]};
  // The values, frozen; the spec constant expressions built from them (kMode == kResolveEdges),
  // folded; then what the now constant branches leave unreachable, removed.
  opt.RegisterPass(spvtools::CreateSetSpecConstantDefaultValuePass(values))
      .RegisterPass(spvtools::CreateFreezeSpecConstantValuePass())
      .RegisterPass(spvtools::CreateFoldSpecConstantOpAndCompositePass())
      .RegisterPass(spvtools::CreateDeadBranchElimPass())
      .RegisterPass(spvtools::CreateCFGCleanupPass())
      .RegisterPass(spvtools::CreateAggressiveDCEPass())
      .RegisterPass(spvtools::CreateEliminateDeadFunctionsPass())
      .RegisterPass(spvtools::CreateEliminateDeadConstantPass());
  // The validation layers check the module the driver gets; the optimizer need not check its
  // input (the build's glslang output) again.
  spvtools::OptimizerOptions options;
  options.set_run_validator(false);
  std::vector<uint32_t> out;
  if (!opt.Run(code.data(), code.size(), &out, options)) {
    return absl::InternalError(absl::StrCat("specializing SPIR-V on the host failed: ",
                                            first_message.empty() ? "no message" : first_message));
  }
  return out;
}

bool ForEachSpirvInstruction(
    std::span<const uint32_t> code,
    absl::FunctionRef<void(uint32_t opcode, std::span<const uint32_t> instruction)> fn) {
  constexpr uint32_t kMagic = 0x07230203;
  constexpr size_t kHeaderWords = 5;
  if (code.size() < kHeaderWords || code[0] != kMagic) return false;
  for (size_t i = kHeaderWords; i < code.size();) {
    const uint32_t count = code[i] >> 16;
    if (count == 0 || i + count > code.size()) return false;
    fn(code[i] & 0xffffu, code.subspan(i, count));
    i += count;
  }
  return true;
}

bool HasSpecializationConstants(std::span<const uint32_t> code) {
  constexpr uint32_t kOpDecorate = 71, kSpecId = 1;
  bool found = false;
  ForEachSpirvInstruction(code, [&](uint32_t op, std::span<const uint32_t> words) {
    found |= op == kOpDecorate && words.size() >= 3 && words[2] == kSpecId;
  });
  return found;
}

}  // namespace tessera::vk
