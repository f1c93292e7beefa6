#include "runtime/core/nearest_name.h"

#include <algorithm>
#include <vector>

namespace mocap {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

std::string_view nearest_name(std::span<const std::string_view> names, std::string_view typed) {
  std::string_view best;
  std::size_t best_d = std::max<std::size_t>(2, typed.size() / 3) + 1;
  for (std::string_view n : names) {
    const std::size_t d = edit_distance(n, typed);
    if (d < best_d) best_d = d, best = n;
  }
  return best;
}

}  // namespace mocap
