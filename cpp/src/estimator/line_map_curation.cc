#include "linnet/estimator/line_map_curation.h"

#include <cmath>
#include <stdexcept>

namespace linnet {

std::vector<MapLine> curateLineMap(const std::vector<MapLine>& lines, const LineMapOptions& options,
                                   LineMapCurationStats* stats) {
  if (!(options.max_sigma_m >= 0.0))
    throw std::invalid_argument("line map options: max_sigma_m must be >= 0 m (infinity: every line)");
  const bool publish_all = std::isinf(options.max_sigma_m);
  std::vector<MapLine> out;
  out.reserve(lines.size());
  for (const MapLine& l : lines) {
    const bool segment = l.a.allFinite() && l.b.allFinite() && l.a != l.b;
    if (segment && (publish_all || l.sigma_m <= options.max_sigma_m)) out.push_back(l);
  }
  if (stats) {
    stats->input = lines.size();
    stats->published = out.size();
    stats->uncertain = lines.size() - out.size();
  }
  return out;
}

}  // namespace linnet
