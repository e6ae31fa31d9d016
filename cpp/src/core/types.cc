// Translation unit for the core layer (most of core is header-only).
#include "linnet/core/types.h"
#include "linnet/core/pose.h"
#include "linnet/core/options.h"

namespace linnet {
namespace {
// Instantiating the headers here makes them compile with the project's warning flags.
[[maybe_unused]] Pose composeForCompileCheck(const Pose& a, const Pose& b) { return a * b.inverse(); }
}  // namespace
}  // namespace linnet
