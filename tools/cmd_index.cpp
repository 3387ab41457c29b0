// `rayscan index CLOUD... -o SITE.rsi`: builds the index file of one or more point cloud files
// (a site delivered as tiles is one index) out of core. Parsing and printing only; the build is
// rayscan::io::build_index_file (index_file.hpp).
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/io/index_file.hpp"

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>

namespace rayscan::cli {

Runner add_index_command(CLI::App& app) {
  auto* sub = app.add_subcommand("index", "Build an index file (.rsi) of one or more point cloud files "
                                          "out of core (external sort by Morton code), for mmap'd queries and renders");
  struct Opts {
    std::vector<std::string> inputs;
    std::string output, attributes = "none", memory = "4G", layout = "adaptive", temp_dir, positions = "compact";
    std::uint32_t capacity = 32;
    unsigned depth = 6, max_depth = 21;
    bool quiet = false;
  };
  auto o = std::make_shared<Opts>();
  sub->add_option("CLOUD", o->inputs, "input point cloud files (tiles of one site, same CRS)")->required();
  sub->add_option("-o,--output", o->output, "index file to write (.rsi)")->required();
  sub->add_option("--attributes", o->attributes,
                  "attributes to store besides positions: id,rgb,intensity,classification,gps_time | all | none "
                  "(id: the original point ids, 4 bytes/point; without it outputs are in index order)")
      ->capture_default_str();
  sub->add_option("--memory", o->memory, "memory budget of the external sort (e.g. 4G, 512M)")->capture_default_str();
  sub->add_option("--layout", o->layout, "octree layout: adaptive | fixed")->capture_default_str();
  sub->add_option("--capacity", o->capacity, "adaptive: points per leaf before a split")->capture_default_str();
  sub->add_option("--depth", o->depth, "fixed: leaf depth")->capture_default_str();
  sub->add_option("--max-depth", o->max_depth, "adaptive: deepest level (<= 21)")->capture_default_str();
  sub->add_option("--positions", o->positions,
                  "compact: the LAS int32 grid (LAS/LAZ inputs on one scale/offset) or float32 when exact, "
                  "else float64 | float64: always 24 bytes per point (docs/index-format.md)")
      ->check(CLI::IsMember({"compact", "float64"}))
      ->capture_default_str();
  sub->add_option("--temp-dir", o->temp_dir, "folder for the sort runs (default: the output's folder)");
  sub->add_flag("-q,--quiet", o->quiet, "no progress on stderr");
  return [o]() -> int {
    require_single_process("rayscan index");
    io::IndexBuildOptions opt;
    try {
      opt.config.layout = parse_octree_layout(o->layout);
      opt.config.capacity = o->capacity;
      opt.config.depth = o->depth;
      opt.config.max_depth = o->max_depth;
      opt.memory_bytes = io::parse_byte_size(o->memory);
      io::AttributeSet a = io::AttributeSet::parse(o->attributes);
      if (o->attributes == "all") a = io::AttributeSet::parse("id,rgb,intensity,classification,gps_time");
      opt.attributes = a;
      opt.compact_positions = o->positions == "compact";
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    if (!io::is_index_file(o->output)) throw UsageError(o->output + ": the index file name must end in .rsi");
    opt.temp_dir = o->temp_dir;
    const auto t0 = std::chrono::steady_clock::now();
    auto secs = [t0] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    if (!o->quiet)
      opt.progress = [&secs](const char* phase, std::uint64_t done, std::uint64_t total) {
        const double s = secs();
        if (total > 0)
          std::fprintf(stderr, "\rindex: %-5s %6.1f%%  %llu / %llu points  %.1f M points/s   ", phase,
                       100.0 * static_cast<double>(done) / static_cast<double>(total),
                       static_cast<unsigned long long>(done), static_cast<unsigned long long>(total),
                       s > 0 ? static_cast<double>(done) / s / 1e6 : 0.0);
        else
          std::fprintf(stderr, "\rindex: %-5s %llu points   ", phase, static_cast<unsigned long long>(done));
        std::fflush(stderr);
      };
    std::vector<std::filesystem::path> in(o->inputs.begin(), o->inputs.end());
    const io::IndexBuildStats st = io::build_index_file(in, o->output, opt);
    const double s = secs();
    if (!o->quiet) std::fprintf(stderr, "\n");
    for (const std::string& n : st.notes) std::cerr << "note: " << n << "\n";
    std::printf("%s: %llu points, %llu nodes, depth %u, %llu sort runs, %s, positions %s; %.2f bytes/point; %.2f s (%.2f M points/s)\n",
                o->output.c_str(), static_cast<unsigned long long>(st.points),
                static_cast<unsigned long long>(st.nodes), st.depth, static_cast<unsigned long long>(st.runs),
                st.attributes.bits ? st.attributes.to_string().c_str() : "positions only", to_string(st.positions),
                st.points ? static_cast<double>(st.file_bytes) / static_cast<double>(st.points) : 0.0, s,
                s > 0 ? static_cast<double>(st.points) / s / 1e6 : 0.0);
    return 0;
  };
}

}  // namespace rayscan::cli
