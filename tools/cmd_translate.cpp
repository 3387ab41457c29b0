// `rayscan translate IN OUT`: point file conversion (lossless LAS <-> LAZ; any input to COPC, LAS, LAZ, PLY, ...). Parsing
// and printing only; the job is rayscan::jobs::run_translate (rayscan/jobs/translate.hpp).
#include "commands.hpp"
#include "copc_summary.hpp"
#include "phase_progress.hpp"
#include "processes.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/io/point_extensions.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/translate.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iostream>
#include <memory>
#include <vector>

namespace rayscan::cli {

namespace {

/// The numbers of `text`, comma-separated (no spaces), for the option `flag`; `expected` says what
/// the option takes. Throws UsageError naming the flag for anything else.
std::vector<double> parse_numbers(const std::string& flag, const std::string& text, const std::string& expected) {
  std::vector<double> v;
  std::size_t at = 0;
  while (true) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    const char* b = text.data() + at;
    const char* e = text.data() + end;
    if (b < e && *b == '+') ++b;
    double x = 0;
    const auto [p, ec] = std::from_chars(b, e, x);
    if (ec != std::errc() || p != e || !std::isfinite(x))
      throw UsageError(flag + " '" + text + "': expected " + expected);
    v.push_back(x);
    if (end == text.size()) return v;
    at = end + 1;
  }
}

}  // namespace

Runner add_translate_command(CLI::App& app) {
  auto* sub = app.add_subcommand("translate", "Convert point files (like `pdal translate`): LAS <-> LAZ losslessly "
                                              "(same header, VLRs/EVLRs and byte-identical point records); any "
                                              "readable file to .copc.laz (COPC 1.0), .las, .laz, .ply, .pcd or text (.xyz, .csv, .txt) by OUT's extension");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("auto");
  auto chunk = std::make_shared<std::uint32_t>(50000);
  auto memory = std::make_shared<std::string>("4G");
  sub->add_option("IN", *in, "input point file (" + io::extension_list(io::point_cloud_input_extensions()) +
                                 ") or index file (.rsi: its points in the sources' order, with the attributes it stores)")
      ->required();
  sub->add_option("OUT", *out, "output file: .las, .laz, .copc.laz (COPC 1.0: LAZ 1.4 with an octree of grid subsamples), "
                                ".ply (binary, double x y z), .pcd (binary; x y z float when exact, else double) or "
                                "text with a header line (.xyz and .txt space-separated, .csv comma-separated)")
      ->required();
  sub->add_option("--format", *format,
                  "the output's compression: auto (by OUT's extension), las or laz; an OUT whose extension names "
                  "the other format is refused")
      ->check(one_of({"auto", "las", "laz"}))
      ->capture_default_str();
  auto* chunk_option =
      sub->add_option("--chunk-size", *chunk,
                      "LAZ output: points per chunk (refused for other outputs, COPC too: one chunk per octree node)")
          ->transform(integer_in(1, 0xFFFFFFFEll))
          ->capture_default_str();
  sub->add_option("--memory", *memory,
                  "COPC output: memory budget of the build, a byte size: 12 bytes per point plus 256 MiB (e.g. "
                  "4G, 512M); checked for every output")
      ->capture_default_str();
  auto temp_dir = std::make_shared<std::string>();
  sub->add_option("--temp-dir", *temp_dir,
                  "COPC output: existing folder of the build's temporary records file (default: OUT's folder); "
                  "checked for every output");
  auto scale = std::make_shared<std::string>();
  auto offset = std::make_shared<std::string>();
  sub->add_option("--scale", *scale,
                  "LAS, LAZ and COPC output: the coordinates' step in file units, S for x, y and z or SX,SY,SZ "
                  "(each a finite number > 0; as PDAL writers.las scale_x; e.g. 0.0001). Default: the input's LAS "
                  "scale, else the coarsest of 1, 0.1, 0.01, 0.001 the points lie on, else 0.001 (coarsened "
                  "tenfold until the extent fits 32-bit integers). Refused for other outputs");
  sub->add_option("--offset", *offset,
                  "LAS, LAZ and COPC output: auto (the points' low corner rounded down to 1000 steps) or X,Y,Z "
                  "(file units; as writers.las offset_x). Default: the input's LAS offset with its scale, else auto "
                  "(also when --scale is given)");
  auto quiet = std::make_shared<bool>(false);
  sub->add_flag("-q,--quiet", *quiet, "no progress or notes on stderr");
  return [in, out, format, chunk, chunk_option, memory, temp_dir, scale, offset, quiet]() -> int {
    require_single_process("rayscan translate");
    jobs::TranslateJobOptions job;
    job.in = *in;
    job.out = *out;
    // --format sets LAS or LAZ for a name that does not say which; a name that says the other
    // format (x.laz with --format las) would be a file whose name lies.
    if (*format != "auto" && !io::is_copc_output(*out)) {  // (a .copc.laz name: the job's own message)
      const std::string ext = rayscan::lower_extension(*out);
      if (ext != "." + *format && rayscan::has_extension(*out, io::point_cloud_output_extensions()))
        throw UsageError("--format " + *format + ": OUT '" + *out + "' names another format (" + ext +
                         "); give a ." + *format + " name, or --format auto");
    }
    job.compression = *format == "las" ? jobs::LasCompression::las
                      : *format == "laz" ? jobs::LasCompression::laz : jobs::LasCompression::by_extension;
    if (chunk_option->count() > 0) job.chunk_size = *chunk;  // unset: the job's default, and no refusal
    job.memory = *memory;
    job.temp_dir = *temp_dir;
    if (!scale->empty()) job.scale = parse_numbers("--scale", *scale, "S or SX,SY,SZ (numbers > 0)");
    if (*offset == "auto") {
      job.auto_offset = true;
    } else if (!offset->empty()) {
      const std::vector<double> v = parse_numbers("--offset", *offset, "auto or X,Y,Z (three finite numbers)");
      if (v.size() != 3) throw UsageError("--offset '" + *offset + "': expected auto or X,Y,Z (three finite numbers)");
      job.offset = Vec3(v[0], v[1], v[2]);
    }
    const PhaseProgress progress("translate", *quiet);
    job.progress = progress;
    const jobs::TranslateJobResult r = jobs::run_translate(job);
    progress.finish();
    for (const std::string& w : r.warnings) std::cerr << "rayscan translate: warning: " << w << "\n";  // also with -q
    const std::string ext = rayscan::lower_extension(*out);
    const char* written = job.compression != jobs::LasCompression::by_extension ? (r.compressed ? "LAZ" : "LAS")
                          : ext == ".ply"                                      ? "PLY"
                          : ext == ".pcd"                                      ? "PCD"
                          : ext == ".las" || ext == ".laz"                     ? (r.compressed ? "LAZ" : "LAS")
                                                                               : "text";
    if (r.copc) {
      print_copc_summary("rayscan translate", *out, *r.copc, *quiet);
      return 0;
    }
    std::cout << *out << ": " << r.points << " points, " << written << ", " << r.out_bytes
              << " bytes";
    if (r.compressed) std::cout << " in " << r.chunks << " chunks";
    std::cout << " (input " << r.in_bytes << " bytes)\n";
    return 0;
  };
}

}  // namespace rayscan::cli
