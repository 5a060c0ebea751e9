// roomseg-bench: one line of the VRF's chatter saying how its inference labelled the conditional
// field's nodes, e.g. "roomseg field nodes: room 40 hallway 0 doorway 0".
//
// Why: after inference the authors keep a class's regions only when that class has more than one
// region in the map (`map_contours.size() > 1` in voronoi_random_field_segmentation.cpp), so a map
// whose nodes are all labelled one class can end with no room at all. `make ipa-env` compiles a
// copy of the authors' file (in the build folder) with a call here after their
// `belief_propagation.arg(best_labels);`; the line goes to std::cout, the algorithms' own progress
// stream, which the driver shows on stderr with --verbose 1 and drops otherwise. It changes nothing
// the VRF computes (benchmark/commands/maintainer/vrf_causes.py reads it).
#ifndef ROOMSEG_IPA_VRF_LABELS_H
#define ROOMSEG_IPA_VRF_LABELS_H
#include <cstddef>
#include <iostream>
#include <vector>

template <class Label>
inline void roomseg_vrf_labels(const std::vector<Label>& labels) {
  std::size_t n[4] = {0, 0, 0, 0};  // room, hallway, doorway (the server's order), anything else
  for (const Label l : labels) ++n[static_cast<std::size_t>(l) < 3 ? static_cast<std::size_t>(l) : 3];
  std::cout << "roomseg field nodes: room " << n[0] << " hallway " << n[1] << " doorway " << n[2];
  if (n[3]) std::cout << " other " << n[3];
  std::cout << std::endl;
}
#endif
