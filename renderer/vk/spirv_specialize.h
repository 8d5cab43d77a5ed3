#pragma once
// Specialization on the host, for drivers that keep the code a specialization constant leaves
// unreachable (DeviceInfo::host_specialization: SwiftShader runs it under an empty lane mask, and
// runs every workgroup of a shader that holds a barrier anywhere as coroutines). The renderer's
// shaders pick modes, effects and sample counts by specialization constants (README:
// "Specialization, not branches"); where the driver folds them (lavapipe, GPUs) this is not used.
#include <cstdint>
#include <span>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/statusor.h"

namespace tessera::vk {

// `code` with specialization constant i set to constants[i] (the SpecId i; a bool's value is 0
// or 1; ids the module lacks are ignored) and frozen into a plain constant, and the branches,
// blocks, functions and constants the values leave dead removed (SPIRV-Tools' optimizer). The
// result needs no VkSpecializationInfo. An error names the optimizer's first message.
absl::StatusOr<std::vector<uint32_t>> SpecializeSpirv(std::span<const uint32_t> code,
                                                      std::span<const uint32_t> constants);

// Whether `code` declares any specialization constant (an OpDecorate ... SpecId): a shader
// without one needs no specializing, whatever constants its pipeline passes.
bool HasSpecializationConstants(std::span<const uint32_t> code);

// Calls fn(opcode, instruction) for each instruction of `code` after the module's header, the
// instruction's words from its opcode word on. False where `code` is not a SPIR-V module (its
// magic number) whose instructions end where its words do.
bool ForEachSpirvInstruction(
    std::span<const uint32_t> code,
    absl::FunctionRef<void(uint32_t opcode, std::span<const uint32_t> instruction)> fn);

}  // namespace tessera::vk
