// `rayscan index CLOUD... -o SITE.rsi`: builds the index file of one or more point cloud files
// (a site delivered as tiles is one index) out of core. Parsing and printing only; the job is
// rayscan::jobs::run_index (rayscan/jobs/index.hpp).
#include "commands.hpp"
#include "copc_summary.hpp"
#include "phase_progress.hpp"
#include "processes.hpp"

#include "rayscan/base/interrupt.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/octree/any_index.hpp"

#include <signal.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::cli {

namespace {

/// Thrown by the progress callback once SIGINT, SIGTERM or SIGHUP arrived: the build unwinds, and
/// its temporary output and sort runs are removed by their owners (AtomicFile, the runs folder),
/// so an interrupted build leaves nothing behind, like a failed one.
struct Interrupted : std::runtime_error {
  int signal;
  explicit Interrupted(int s)
      : std::runtime_error(std::string("interrupted by ") + (s == SIGINT ? "SIGINT" : s == SIGTERM ? "SIGTERM" : "SIGHUP") +
                           ": temporary files removed, no index written"),
        signal(s) {}
};

/// The octree layouts of the external-memory build, in the order --help and messages list them
/// (not layered, which that build lacks).
constexpr std::array kIndexFileLayouts = {OctreeLayout::adaptive, OctreeLayout::fixed};

}  // namespace

Runner add_index_command(CLI::App& app) {
  auto* sub = app.add_subcommand("index", "Build an index file (.rsi) of one or more point cloud files "
                                          "out of core (external sort by Morton code), for mmap'd queries and renders");
  struct Opts {
    std::vector<std::string> inputs;
    std::string output, attributes = "none", memory = jobs::IndexJobOptions{}.memory, temp_dir, positions = "compact";
    std::string layout = to_string(OctreeLayout::adaptive);
    std::uint32_t capacity = default_capacity(OctreeLayout::adaptive);
    unsigned depth = 6, max_depth = 21;
    bool quiet = false;
  };
  auto o = std::make_shared<Opts>();
  sub->add_option("CLOUD", o->inputs, "input point cloud files (tiles of one site, same CRS)")->required();
  sub->add_option("-o,--out,--output", o->output, "index file to write (.rsi), or a COPC 1.0 file (.copc.laz; one CLOUD, "
                                            "12 bytes per point within --memory)")->required();
  CLI::Option* attributes = sub->add_option("--attributes", o->attributes,
                  "attributes to store besides positions: id,rgb,intensity,classification,gps_time | all | none "
                  "(id: the original point ids, 4 bytes/point; without it outputs are in index order)")
      ->capture_default_str();
  sub->add_option("--memory", o->memory, "memory budget of the external sort (e.g. 4G, 512M); for .copc.laz of the "
                                         "build (12 bytes per point plus 256 MiB)")->capture_default_str();
  std::vector<std::string> layouts;
  for (OctreeLayout l : kIndexFileLayouts) layouts.emplace_back(to_string(l));
  CLI::Option* layout_opt =
      sub->add_option("--layout", o->layout, "octree layout")->check(one_of(layouts))->capture_default_str();
  CLI::Option* capacity = sub->add_option("--capacity", o->capacity, "adaptive: points per leaf before a split (fixed: an error)")
                              ->capture_default_str()
                              ->transform(integer_in(1, 0xFFFFFFFF));
  CLI::Option* depth = sub->add_option("--depth", o->depth, "fixed: leaf depth, 0..21 (adaptive: an error)")
                           ->capture_default_str()
                           ->transform(integer_in(0, 21));
  CLI::Option* max_depth = sub->add_option("--max-depth", o->max_depth, "adaptive: deepest level, 1..21 (fixed: an error)")
                               ->capture_default_str()
                               ->transform(integer_in(1, 21));
  CLI::Option* positions = sub->add_option("--positions", o->positions,
                  "compact: the LAS int32 grid (LAS/LAZ inputs on one scale/offset) or float32 when exact, "
                  "else float64 | float64: always 24 bytes per point (docs/index-format.md)")
      ->check(one_of({"compact", "float64"}))
      ->capture_default_str();
  sub->add_option("--temp-dir", o->temp_dir, "existing folder for the sort runs, or of a .copc.laz output's temporary records file (default: the output's folder)");
  sub->add_flag("-q,--quiet", o->quiet, "no progress or notes on stderr");
  return [o, attributes, layout_opt, capacity, depth, max_depth, positions]() -> int {
    require_single_process("rayscan index");
    jobs::IndexJobOptions job;
    job.config.layout = parse_octree_layout(o->layout);  // (one of the names --layout checked)
    // An option the chosen layout does not use is refused rather than ignored, by the library's
    // rule (check_applicable; its OptionError is printed with the flags' names; the job refuses
    // the layered layout, which the external-memory build lacks). A COPC output has its own octree.
    if (io::is_copc_output(o->output)) {
      for (const CLI::Option* opt : {attributes, layout_opt, capacity, depth, max_depth, positions})
        if (opt->count() > 0)
          throw UsageError(opt->get_name() + " applies to an index file (.rsi), not to a COPC output (.copc.laz)");
    } else {
      GivenIndexOptions given;
      given.capacity = capacity->count() > 0;
      given.max_depth = max_depth->count() > 0;
      given.depth = depth->count() > 0;
      IndexChoiceWords words;
      words.option = "--layout ";
      words.layouts = true;
      for (OctreeLayout l : kIndexFileLayouts) words.types.push_back(octree_index_type(l));
      check_applicable(octree_index_type(job.config.layout), given, words);
    }
    job.config.capacity = o->capacity;
    job.config.depth = o->depth;
    job.config.max_depth = o->max_depth;
    job.memory = o->memory;
    job.attributes = o->attributes;
    job.compact_positions = o->positions == "compact";
    job.inputs.assign(o->inputs.begin(), o->inputs.end());
    job.output = o->output;
    job.temp_dir = o->temp_dir;
    const auto t0 = std::chrono::steady_clock::now();
    auto secs = [t0] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    // The progress callback runs every few million points in every phase (and once more before
    // the output is renamed into place); it is also where an interrupt stops the build: the first
    // SIGINT, SIGTERM or SIGHUP is only recorded (defer_interrupts), a second one ends the process
    // at once, as a user pressing Ctrl-C twice expects, its temporaries removed by the handler.
    const PhaseProgress progress("index", o->quiet);
    job.progress = [progress](const char* phase, std::uint64_t done, std::uint64_t total) {
      if (const int sig = pending_interrupt(); sig != 0) throw Interrupted(sig);
      progress(phase, done, total);
    };
    defer_interrupts();
    jobs::IndexJobResult r;
    try {
      r = jobs::run_index(job);
    } catch (const Interrupted& e) {
      progress.finish(false);
      std::cerr << "rayscan index: " << e.what() << "\n";
      return 128 + e.signal;  // the shell's convention for a command ended by a signal
    }
    const double s = secs();
    progress.finish();
    if (r.copc) {
      for (const std::string& w : r.copc->warnings) std::cerr << "rayscan index: warning: " << w << "\n";  // also with -q
      print_copc_summary("rayscan index", o->output, *r.copc, o->quiet);
      std::printf("%.2f s (%.2f M points/s)\n", s, s > 0 ? static_cast<double>(r.copc->points) / s / 1e6 : 0.0);
      return 0;
    }
    const io::IndexBuildStats& st = r.stats;
    if (!o->quiet)
      for (const std::string& n : st.notes) std::cerr << "rayscan index: note: " << n << "\n";
    std::printf("%s: %llu points, %llu nodes, depth %u, %s, %s, positions %s; %.2f bytes/point; %.2f s (%.2f M points/s)\n",
                o->output.c_str(), static_cast<unsigned long long>(st.points),
                static_cast<unsigned long long>(st.nodes), st.depth, count_text(st.runs, "sort run").c_str(),
                st.attributes.bits ? st.attributes.to_string().c_str() : "positions only", to_string(st.positions),
                st.points ? static_cast<double>(st.file_bytes) / static_cast<double>(st.points) : 0.0, s,
                s > 0 ? static_cast<double>(st.points) / s / 1e6 : 0.0);
    return 0;
  };
}

}  // namespace rayscan::cli
