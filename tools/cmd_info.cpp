// `rayscan info FILE [--json] [--verify]`: what `pdal info` reports for a point cloud file (streamed
// chunk by chunk) or an index file (.rsi). The job is jobs::run_info (rayscan/jobs/info.hpp); this
// file parses options and prints.
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/io/point_extensions.hpp"
#include "rayscan/jobs/info.hpp"

#include <iostream>
#include <memory>

namespace rayscan::cli {

Runner add_info_command(CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Describe a point cloud file (like `pdal info`): format, "
                                         "counts, recomputed bounds, attributes and their ranges (--stats: mean, standard deviation), CRS "
                                         "(units, WKT; in --json also WKT2 and PROJJSON)");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto verify = std::make_shared<bool>(false);
  auto stats = std::make_shared<bool>(false);
  sub->add_option("FILE", *file,
                  "point cloud file (" + io::extension_list(io::point_cloud_input_extensions()) +
                      ") or index file (.rsi)")
      ->required();
  sub->add_flag("--json", *json, "print one JSON object instead of text");
  sub->add_flag("--verify", *verify, "index files: verify the checksum of every section");
  sub->add_flag("--stats", *stats,
                "add each attribute's mean and standard deviation (population) to its min and max, "
                "like `pdal info --stats` (the same streaming pass)");
  return [file, json, verify, stats]() -> int {
    require_single_process("rayscan info");
    jobs::InfoJobOptions job;
    job.file = *file;
    job.verify = *verify;
    job.stats = *stats;
    const jobs::InfoJobResult r = jobs::run_info(job);
    std::cout << (*json ? jobs::info_report_json(r) + "\n" : jobs::info_report_text(r));
    return 0;
  };
}

}  // namespace rayscan::cli
