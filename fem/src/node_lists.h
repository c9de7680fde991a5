// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Internal to spidarcad_fem: the node-list checks and indexing shared by Compliance
// (condensation.cc) and ColumnCache (column_cache.cc), which both condense a subset of
// their output nodes.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace spidarcad::fem::detail {

// Per node of a mesh: where it stands in the output list and in the condensed subset.
struct NodeListIndex {
  std::vector<int> output_index;  // per mesh node: index in outputs, −1 if not an output
  std::vector<int> subset_index;  // per mesh node: index in subset, −1 if not in it
  std::vector<int> subset_row;    // per subset entry: its index in outputs
};

// Checks that `outputs` holds distinct nodes in [0, num_nodes) and `subset` distinct nodes of
// `outputs`, and indexes both. Throws std::invalid_argument naming `who` ("Compliance"), the
// list (`subset_name`: "condensed", "candidate") and the node.
NodeListIndex IndexNodeLists(const std::string& who, const std::string& subset_name, int num_nodes,
                             const std::vector<int>& outputs, const std::vector<int>& subset);

// For each point b, the k nearest points c != b with allowed[c] != 0, nearest first, as
// #points by k indices (−1 pad when fewer exist): exactly the list of a brute-force search
// ordering (squared distance, index) lexicographically, found through a uniform grid
// (O(#points · k) for points spread over a surface or a volume instead of O(#points²)).
std::vector<int> NearestAllowed(const std::vector<Eigen::Vector3d>& points,
                                const std::vector<char>& allowed, int k);

}  // namespace spidarcad::fem::detail
