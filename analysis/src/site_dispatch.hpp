// The analyses' one dispatch on a site's storage (Site::visit), with COPC in place refused: the
// analyses read a COPC file into memory (SiteOptions::copc_in_place = false).
#pragma once

#include "rayscan/site/site.hpp"

#include <stdexcept>
#include <string>

namespace rayscan::analysis::detail {

/// Returns f(index) for the concrete index of `site`. Throws std::invalid_argument naming `what`
/// for a COPC file queried in place.
template <class R, class F>
R over_site(const Site& site, const char* what, F&& f) {
  return site.visit([&](const auto& index) -> R {
    if constexpr (is_copc_index<decltype(index)>)
      throw std::invalid_argument(std::string(what) +
                                  ": a COPC file queried in place is not supported; read it into memory");
    else
      return f(index);
  });
}

}  // namespace rayscan::analysis::detail
