// "Did you mean": the known name nearest to what a user typed (Levenshtein distance), for
// mistyped commands, flags, config keys and log categories. One rule everywhere: the nearest
// name within max(2, typed/3) edits; none when nothing is that close.
#pragma once

#include <cstddef>
#include <span>
#include <string_view>

namespace mocap {

// Insertions, deletions and substitutions turning `a` into `b`.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The name of `names` nearest to `typed`; empty when none is close enough.
std::string_view nearest_name(std::span<const std::string_view> names, std::string_view typed);

}  // namespace mocap
