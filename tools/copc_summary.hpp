// The summary `rayscan translate` and `rayscan index` print after writing a COPC file.
#pragma once

#include "rayscan/site/copc_writer.hpp"

#include <string>

namespace rayscan::cli {

/// Prints on stdout "<out>: N points, COPC 1.0 (PDRF p, r bytes/record), M nodes, depth D, P
/// hierarchy pages, B bytes (input I bytes)" and one line per level (nodes, points), and, unless
/// `quiet` (the command's -q), the writer's notes on stderr, each prefixed as the command's other
/// lines by `command` ("rayscan translate": "rayscan translate: note: ...").
void print_copc_summary(const std::string& command, const std::string& out, const io::CopcWriteResult& r, bool quiet);

}  // namespace rayscan::cli
