// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "node_lists.h"

#include <stdexcept>

namespace spidarcad::fem::detail {

NodeListIndex IndexNodeLists(const std::string& who, const std::string& subset_name, int num_nodes,
                             const std::vector<int>& outputs, const std::vector<int>& subset) {
  NodeListIndex out;
  out.output_index.assign(num_nodes, -1);
  for (std::size_t a = 0; a < outputs.size(); ++a) {
    const int v = outputs[a];
    if (v < 0 || v >= num_nodes) {
      throw std::invalid_argument(who + ": output node " + std::to_string(v) +
                                  " is out of range [0, " + std::to_string(num_nodes) + ")");
    }
    if (out.output_index[v] >= 0) {
      throw std::invalid_argument(who + ": output node " + std::to_string(v) + " is listed twice");
    }
    out.output_index[v] = static_cast<int>(a);
  }
  out.subset_index.assign(num_nodes, -1);
  out.subset_row.reserve(subset.size());
  for (std::size_t b = 0; b < subset.size(); ++b) {
    const int v = subset[b];
    if (v < 0 || v >= num_nodes || out.output_index[v] < 0) {
      throw std::invalid_argument(who + ": " + subset_name + " node " + std::to_string(v) +
                                  " is not one of the output nodes");
    }
    if (out.subset_index[v] >= 0) {
      throw std::invalid_argument(who + ": " + subset_name + " node " + std::to_string(v) +
                                  " is listed twice");
    }
    out.subset_index[v] = static_cast<int>(b);
    out.subset_row.push_back(out.output_index[v]);
  }
  return out;
}

}  // namespace spidarcad::fem::detail
