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

#include <iostream>
#include <memory>

namespace rayscan::cli {

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
  sub->add_option("--format", *format, "output: auto (by OUT's extension), las or laz")
      ->check(CLI::IsMember({"auto", "las", "laz"}));
  sub->add_option("--chunk-size", *chunk, "points per LAZ chunk (not COPC: one chunk per octree node)")->check(CLI::Range(1u, 0xFFFFFFFEu));
  sub->add_option("--memory", *memory, "COPC output: memory budget of the build: 12 bytes per point plus 256 MiB (e.g. 4G, 512M)")
      ->capture_default_str();
  auto quiet = std::make_shared<bool>(false);
  sub->add_flag("-q,--quiet", *quiet, "no progress or notes on stderr");
  return [in, out, format, chunk, memory, quiet]() -> int {
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
    job.chunk_size = *chunk;
    job.memory = *memory;
    const PhaseProgress progress("translate", *quiet);
    job.progress = progress;
    const jobs::TranslateJobResult r = jobs::run_translate(job);
    progress.finish();
    const std::string ext = rayscan::lower_extension(*out);
    const char* written = job.compression != jobs::LasCompression::by_extension ? (r.compressed ? "LAZ" : "LAS")
                          : ext == ".ply"                                      ? "PLY"
                          : ext == ".pcd"                                      ? "PCD"
                          : ext == ".las" || ext == ".laz"                     ? (r.compressed ? "LAZ" : "LAS")
                                                                               : "text";
    if (r.copc) {
      print_copc_summary(*out, *r.copc, *quiet);
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
