#pragma once
// Private to dicer/verify*.cpp: the search for coincident fine nodes on the
// coarse boundary facets (verify_coincident.cpp).
#include <functional>
#include <string>
#include <vector>

#include "dicer/verify.hpp"

namespace dicer::detail {

// One boundary facet: local face `slot` (volume) or local edge `slot`
// (surface) of coarse element `element`.
struct Facet {
  Id element;
  int slot;
};

// Adds to r.coincident_nodes (fine nodes sharing bit-identical coordinates
// with another node id), r.coincident_interface (of those, on coarse
// entities that coincide too) and r.near_coincident (closer than tol, not
// identical); a few examples through note().
void find_coincident_nodes(const FineMesh& mesh, const std::vector<Facet>& facets, double tol, VerifyReport& r,
                           const std::function<void(const std::string&)>& note);

}  // namespace dicer::detail
