// The command line as one tool: integers read in decimal, one seed rule, option values checked
// when the options are parsed, every error naming its option, a mistyped command named, and one
// name per concept (query's cloud positional, --sky-rays and --chunk-size as aliases). Each runs
// the real program.
#include <gtest/gtest.h>

#include "../common/run_command.hpp"
#include "jobs_test_util.hpp"
#include "rayscan/camera/camera.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using rayscan::test::data_file;
using rayscan::test::file_bytes;
using rayscan::test::quoted;
using rayscan::test::rayscan_cli;
using rayscan::test::temp_dir;

namespace {

/// A fresh folder of this test process's scratch folder.
std::filesystem::path fresh(const std::string& name) {
  const std::filesystem::path dir = temp_dir() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// Two vertical rays over autzen_trim.las's middle (each meets far more than 10 points).
std::filesystem::path two_rays(const std::filesystem::path& dir) {
  std::ofstream(dir / "rays.csv") << "ox,oy,oz,dx,dy,dz\n636500,849200,1000,0,0,-1\n636600,849300,1000,0,0,-1\n";
  return dir / "rays.csv";
}

/// The lines of `text`.
std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> v;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

}  // namespace

// A leading zero is not octal (CLI11 alone converts integers with strtoull(s, .., 0), which reads
// `--k 010` as 8 and refuses `--k 08`). Oracles: the rows the query writes per ray, the effective
// scene `render --print-scene` prints, the chunk size `db import --json` reports and the
// chunks it made (ceil(1065 / 10)), the leaf depth `index` reports.
TEST(CliOptions, IntegersAreDecimalWithALeadingZero) {
  const auto dir = fresh("decimal");
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::string query = "query -q " + las + " --rays " + quoted(two_rays(dir)) + " --k ";
  const std::pair<std::string, std::size_t> ks[] = {{"010", 10}, {"08", 8}, {"+012", 12}};
  for (const auto& [k, rows] : ks) {
    const auto r = rayscan_cli(query + k);
    ASSERT_EQ(r.code, 0) << k << ": " << r.out;
    EXPECT_EQ(lines_of(r.out).size(), 1 + 2 * rows) << k;  // the header, then k rows per ray
  }
  auto r = rayscan_cli("render " + las + " --print-scene --spp 010 --width 010 --seed 010");
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json scene = nlohmann::json::parse(r.out);
  EXPECT_EQ(scene["spp"], 10);
  EXPECT_EQ(scene["seed"], 10);
  EXPECT_EQ(scene["camera"]["width"], 10);
  const std::string small = quoted(data_file("las/point-color.las"));
  r = rayscan_cli("db import -q " + small + " -o " + quoted(dir / "a.sqlite") + " --chunk 010 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json import = nlohmann::json::parse(r.out);
  EXPECT_EQ(import["chunk_size"], 10);
  EXPECT_EQ(import["chunks"], (import["points"].get<int>() + 9) / 10);
  r = rayscan_cli("index -q " + small + " -o " + quoted(dir / "a.rsi") + " --layout fixed --depth 010");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(", depth 10, "), std::string::npos) << r.out;
  // Still whole numbers in range, in the integer_in words.
  r = rayscan_cli(query + "0x10");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: --k: expected an integer >= 1, got '0x10' (see --help)\n");
  std::filesystem::remove_all(dir);
}

// visibility --seed follows render's rule (one validator): -1 and a seed past 2^64-1 are refused
// (not wrapped), and 010 is 10. Oracle: the refusals' lines, and the sky view of --seed 010
// equal to that of --seed 10, byte for byte.
TEST(CliOptions, SeedsAreUnsigned64BitDecimalsInEveryCommand) {
  const auto dir = fresh("seed");
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::pair<std::string, std::string> commands[] = {{"render", " --print-scene"}, {"visibility", " --sky-view 4"}};
  for (const auto& [command, rest] : commands) {
    for (const char* seed : {"-1", "18446744073709551616", "1.5"}) {
      const auto r = rayscan_cli(command + " " + las + rest + " --seed " + seed);
      EXPECT_EQ(r.code, 2) << command << " " << seed;
      EXPECT_EQ(r.out, "rayscan " + command + ": --seed: expected an unsigned 64-bit integer, got '" +
                           seed + "' (see --help)\n");
    }
  }
  const std::string sky = "visibility -q " + las + " --sky-view 16 -o ";
  ASSERT_EQ(rayscan_cli(sky + quoted(dir / "a.las") + " --seed 010").code, 0);
  ASSERT_EQ(rayscan_cli(sky + quoted(dir / "b.las") + " --seed 10").code, 0);
  ASSERT_EQ(rayscan_cli(sky + quoted(dir / "c.las") + " --seed 18446744073709551615").code, 0);
  EXPECT_EQ(file_bytes(dir / "a.las"), file_bytes(dir / "b.las"));
  std::filesystem::remove_all(dir);
}

// An unknown --index is refused when the options are parsed, before the cloud is read: the
// output is the one line, with no "read N points" log line before it, and it names the option and
// lists the index types.
TEST(CliOptions, UnknownIndexIsRefusedBeforeTheCloudIsRead) {
  const auto dir = fresh("index_type");
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::string list = "--index: expected octree-adaptive, octree-layered, octree-fixed, kdtree or brute, got '";
  auto r = rayscan_cli("query " + las + " --rays " + quoted(two_rays(dir)) + " --k 1 --index rtree");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: " + list + "rtree' (see --help)\n");
  r = rayscan_cli("visibility " + las + " --sky-view 4 -o " + quoted(dir / "v.las") + " --index foo");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan visibility: " + list + "foo' (see --help)\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "v.las"));
  std::filesystem::remove_all(dir);
}

// index's memory, layout, attribute and temporary-folder errors name their option and list only
// what index accepts (no normals or scalars among the attributes, no layered layout, which the
// build refuses; a missing --temp-dir named as given, not by the hidden sort-run folder or COPC
// records file inside it). db import's temporary folder alike. Nothing is written.
TEST(CliOptions, IndexAndDbImportErrorsNameTheirOption) {
  const auto dir = fresh("index_errors");
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string rsi = quoted(dir / "x.rsi"), copc = quoted(dir / "x.copc.laz");
  const std::string memory = "--memory: size '1Q': expected a positive number with an optional K, M, G or T suffix";
  const std::filesystem::path nx = dir / "nx";
  const std::string missing = nx.string();
  const std::pair<std::string, std::string> cases[] = {
      {"-o " + rsi + " --memory 1Q", memory},
      {"-o " + copc + " --memory 1Q", memory},
      {"-o " + rsi + " --layout foo", "--layout: expected adaptive or fixed, got 'foo' (see --help)"},
      {"-o " + rsi + " --layout layered", "--layout: expected adaptive or fixed, got 'layered' (see --help)"},
      {"-o " + rsi + " --attributes id,colour",
       "--attributes 'colour': expected rgb, intensity, classification, gps_time, id, all or none"},
      {"-o " + rsi + " --attributes normals",
       "--attributes 'normals': expected rgb, intensity, classification, gps_time, id, all or none"},
      {"-o " + rsi + " --temp-dir " + quoted(nx), "--temp-dir '" + missing + "': not an existing folder"},
      {"-o " + copc + " --temp-dir " + quoted(nx), "--temp-dir '" + missing + "': not an existing folder"},
      {"-o " + rsi + " --max-depth 0", "--max-depth: expected an integer in [1, 21], got '0' (see --help)"},
  };
  for (const auto& [args, message] : cases) {
    const auto r = rayscan_cli("index -q " + las + " " + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_EQ(r.out, "rayscan index: " + message + "\n") << args;
  }
  const auto r = rayscan_cli("db import -q " + las + " -o " + quoted(dir / "x.sqlite") + " --temp-dir " + quoted(nx));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --temp-dir '" + missing + "': not an existing folder\n");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  EXPECT_FALSE(std::filesystem::exists(nx));
  std::filesystem::remove_all(dir);
}

// A word where a command belongs that names none is named, with the commands there are, in one
// line and exit code 2 (not CLI11's "A subcommand is required"); so for db's subcommand.
TEST(CliOptions, MistypedCommandIsNamed) {
  auto r = rayscan_cli("visibilty x.las --sky-view 4");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan: unknown command 'visibilty' (expected render, visibility, solar, query, index, info, "
                   "translate, compare, db or version)\n");
  r = rayscan_cli("db imprt x.las");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: unknown command 'imprt' (expected import)\n");
  r = rayscan_cli("--bogus");  // an option: CLI11's own line
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out.find("unknown command"), std::string::npos) << r.out;
}

// One name per concept: query takes its cloud positionally as every other command does (and
// still as --cloud); visibility takes solar's --sky-rays for --sky-view, db import translate's
// --chunk-size for --chunk. Oracle: each spelling's output equal, byte for byte, to the other's.
TEST(CliOptions, QueryCloudPositionalAndSharedNamesAsAliases) {
  const auto dir = fresh("aliases");
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::string rays = " --rays " + quoted(two_rays(dir)) + " --k 5";
  const auto by_flag = rayscan_cli("query -q --cloud " + las + rays);
  const auto positional = rayscan_cli("query -q " + las + rays);
  ASSERT_EQ(by_flag.code, 0) << by_flag.out;
  ASSERT_EQ(positional.code, 0) << positional.out;
  EXPECT_EQ(positional.out, by_flag.out);
  EXPECT_EQ(lines_of(positional.out).size(), 11u);
  const std::string small = quoted(data_file("las/point-color.las"));
  const std::string vis = "visibility -q " + small + " -o ";
  ASSERT_EQ(rayscan_cli(vis + quoted(dir / "view.las") + " --sky-view 8").code, 0);
  ASSERT_EQ(rayscan_cli(vis + quoted(dir / "rays.las") + " --sky-rays 8").code, 0);
  EXPECT_EQ(file_bytes(dir / "view.las"), file_bytes(dir / "rays.las"));
  const auto chunk = rayscan_cli("db import -q " + small + " -o " + quoted(dir / "a.sqlite") + " --chunk 100 --json");
  const auto chunk_size =
      rayscan_cli("db import -q " + small + " -o " + quoted(dir / "b.sqlite") + " --chunk-size 100 --json");
  ASSERT_EQ(chunk.code, 0) << chunk.out;
  EXPECT_EQ(chunk_size.out, chunk.out);
  std::filesystem::remove_all(dir);
}

// An option with several spellings is named in a refusal as it was given, not by CLI11's first
// name for it (nor the job's): CLI11's own checks (a value out of range, an option given twice,
// under each name), the job's (solar's latitude without a longitude) and the output name (-o,
// grouped short options too). Oracle: the command line's own words. Nothing is written.
TEST(CliOptions, AnOptionIsNamedAsItWasGiven) {
  const auto dir = fresh("as_given");
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string vis = "visibility -q " + las + " -o " + quoted(dir / "v.las");
  const std::string sky = ": expected an integer in [1, 1048576], got 'abc' (see --help)\n";
  const std::string db = "db import -q " + las + " -o " + quoted(dir / "x.sqlite");
  const std::string chunk = ": expected an integer in [1, 16777216], got '0' (see --help)\n";
  const std::string solar = "solar -q " + las + " --json --at 2026-06-21T12:00";
  const std::string x_las = quoted(dir / "x.las");
  const std::string sqlite_name = " '" + (dir / "x.las").string() +
                                  "': expected a file name ending in .sqlite, .sqlite3 or .db (a SQLite database)\n";
  const std::pair<std::string, std::string> cases[] = {
      {vis + " --sky-rays abc", "rayscan visibility: --sky-rays" + sky},
      {vis + " --sky-rays=abc", "rayscan visibility: --sky-rays" + sky},
      {vis + " --sky-view abc", "rayscan visibility: --sky-view" + sky},
      {vis + " --sky-rays 4 --sky-view 4",
       "rayscan visibility: --sky-view/--sky-rays: At Most 1 required but received 2 (see --help)\n"},
      {db + " --chunk-size 0", "rayscan db: --chunk-size" + chunk},
      {db + " --chunk 0", "rayscan db: --chunk" + chunk},
      {"solar position --latitude 95 --lon 3 --time 2026-06-21",
       "rayscan solar: --latitude: expected a finite number in [-90, 90], got '95' (see --help)\n"},
      {solar + " --lat 45", "rayscan solar: --lat and --longitude go together\n"},
      {solar + " --latitude 45", "rayscan solar: --latitude and --longitude go together\n"},
      {solar + " --lon -123", "rayscan solar: --latitude and --lon go together\n"},
      {"db import " + las + " --out " + x_las, "rayscan db: --out" + sqlite_name},
      {"db import " + las + " -o " + x_las, "rayscan db: -o" + sqlite_name},
      {"db import " + las + " -qo " + x_las, "rayscan db: -o" + sqlite_name},
  };
  for (const auto& [args, message] : cases) {
    const auto r = rayscan_cli(args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_EQ(r.out, message) << args;
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  std::filesystem::remove_all(dir);
}

// A name from a list is written as --help lists it, in lower case, for every option of index as
// for --layout and --positions (CLI11's check): --attributes ALL is refused as ID is, not read as
// every attribute a reader knows and then refused for normals and scalars the user never named.
// Oracle: the lists `rayscan index --help` prints. Nothing is written.
TEST(CliOptions, NamesFromAListAreWrittenInLowerCase) {
  const auto dir = fresh("lower_case");
  const std::string base = "index -q " + quoted(data_file("las/point-color.las")) + " -o " + quoted(dir / "x.rsi");
  const auto help = rayscan_cli("index --help");
  EXPECT_NE(help.out.find("id,rgb,intensity,classification,gps_time | all | none"), std::string::npos) << help.out;
  const std::string attributes = "': expected rgb, intensity, classification, gps_time, id, all or none\n";
  const std::pair<std::string, std::string> cases[] = {
      {" --layout FIXED", "rayscan index: --layout: expected adaptive or fixed, got 'FIXED' (see --help)\n"},
      {" --positions Float64", "rayscan index: --positions: expected compact or float64, got 'Float64' (see --help)\n"},
      {" --attributes ALL", "rayscan index: --attributes 'ALL" + attributes},
      {" --attributes id,RGB", "rayscan index: --attributes 'RGB" + attributes},
      {" --attributes NONE", "rayscan index: --attributes 'NONE" + attributes},
  };
  for (const auto& [args, message] : cases) {
    const auto r = rayscan_cli(base + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_EQ(r.out, message) << args;
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  std::filesystem::remove_all(dir);
}

namespace {

/// The command names of the "Subcommands:" block of a --help text, in order.
std::vector<std::string> subcommands_in(const std::string& help) {
  std::vector<std::string> names;
  const std::string head = "\nSubcommands:\n";
  const std::size_t at = help.find(head);
  if (at == std::string::npos) return names;
  for (const std::string& l : lines_of(help.substr(at + head.size()))) {
    if (l.empty()) break;
    if (l.size() > 2 && l.compare(0, 2, "  ") == 0 && l[2] != ' ') names.push_back(l.substr(2, l.find(' ', 2) - 2));
  }
  return names;
}

}  // namespace

// Every option that takes a name from a list is refused, when the options are parsed, with one
// line naming the option and listing the names ("rayscan index: --layout: expected adaptive or
// fixed, got 'nope' (see --help)"), not CLI11's "nope not in {adaptive,fixed}". Oracle: each
// command's --help (every command and subcommand that rayscan --help leads to): the options it
// shows with a set of names ("--layout TEXT:{adaptive,fixed}"), that set joined here as a
// sentence's list; and the options found are every list option the commands have.
TEST(CliOptions, EveryNameFromAListIsRefusedWithTheList) {
  std::vector<std::string> commands;
  for (const std::string& c : subcommands_in(rayscan_cli("--help").out)) {
    commands.push_back(c);
    for (const std::string& sub : subcommands_in(rayscan_cli(c + " --help").out)) commands.push_back(c + " " + sub);
  }
  ASSERT_GE(commands.size(), 10u);
  const std::regex with_set(R"(^  ((?:-[^ ,]+,)*(-[^ ,]+)) +[A-Z]+:\{([^}]*)\})");
  std::set<std::string> found;
  for (const std::string& command : commands) {
    for (const std::string& line : lines_of(rayscan_cli(command + " --help").out)) {
      std::smatch m;
      if (!std::regex_search(line, m, with_set)) continue;
      const std::string option = m[2];
      std::vector<std::string> names;
      std::istringstream set(m[3].str());
      for (std::string n; std::getline(set, n, ',');) names.push_back(n);
      std::string list;  // "a, b or c"
      for (std::size_t k = 0; k < names.size(); ++k)
        list += (k == 0 ? "" : k + 1 == names.size() ? " or " : ", ") + names[k];
      found.insert(command + " " + option);
      const auto r = rayscan_cli(command + " " + option + " nope");
      EXPECT_EQ(r.code, 2) << command << " " << option;
      const std::string top = command.substr(0, command.find(' '));  // (the line names the first command)
      EXPECT_EQ(r.out, "rayscan " + top + ": " + option + ": expected " + list + ", got 'nope' (see --help)\n");
    }
  }
  const std::set<std::string> want = {"render --aov",         "render --primitive",
                                      "render --ortho-colour", "visibility --primitive",
                                      "visibility --index",    "visibility --sky-weighting",
                                      "solar --primitive",     "solar --index",
                                      "query --index",         "query --order",
                                      "index --layout",        "index --positions",
                                      "translate --format"};
  EXPECT_EQ(found, want);
}

// A note is a line prefixed as every other line of its command, "rayscan translate: note: ...",
// from translate and index writing COPC and index writing an index file; -q leaves none. Oracle:
// the input's point data record format (byte 104 of its LAS header), which COPC writes as 7, and
// the attribute the input lacks (point-color.las has no GPS time: PDRF 2).
TEST(CliOptions, NotesArePrefixedWithTheirCommand) {
  const auto dir = fresh("notes");
  const std::filesystem::path las = data_file("las/point-color.las");
  const int pdrf = static_cast<unsigned char>(file_bytes(las).at(104));
  ASSERT_EQ(pdrf, 2);  // RGB, no GPS time
  const std::string copc_note = "note: point data record format " + std::to_string(pdrf) +
                                " written as 7 (COPC allows 6, 7 and 8)";
  const std::pair<std::string, std::string> runs[] = {
      {"translate " + quoted(las) + " " + quoted(dir / "t.copc.laz"), "rayscan translate: " + copc_note},
      {"index " + quoted(las) + " -o " + quoted(dir / "i.copc.laz"), "rayscan index: " + copc_note},
      {"index " + quoted(las) + " -o " + quoted(dir / "i.rsi") + " --attributes rgb,gps_time",
       "rayscan index: note: " + las.string() + " has no gps_time: not stored"},
  };
  for (const auto& [args, note] : runs) {
    auto r = rayscan_cli(args);
    ASSERT_EQ(r.code, 0) << args << ": " << r.out;
    std::vector<std::string> notes;
    for (const std::string& line : lines_of(r.out))
      if (line.find("note:") != std::string::npos) notes.push_back(line);
    EXPECT_EQ(notes, std::vector<std::string>{note}) << args << ":\n" << r.out;
    r = rayscan_cli(args + " -q");
    ASSERT_EQ(r.code, 0) << args << ": " << r.out;
    EXPECT_EQ(r.out.find("note:"), std::string::npos) << r.out;
  }
  std::filesystem::remove_all(dir);
}

// Help texts give units and defaults, and range errors read as the other number errors (not
// CLI11's Range text, "-30.000000"). The image size's limit comes from kMaxImageSide.
TEST(CliOptions, HelpStatesDefaultsAndRangesReadably) {
  for (const char* command : {"render", "visibility", "query"}) {
    const auto help = rayscan_cli(std::string(command) + " --help");
    EXPECT_NE(help.out.find("Worker threads, 0 = all cores (default 0)"), std::string::npos) << command;
  }
  const auto db = rayscan_cli("db import --help");
  EXPECT_NE(db.out.find("--memory TEXT=4G"), std::string::npos) << db.out;
  const auto render = rayscan_cli("render --help");
  const std::string side = "in pixels, in [1, " + std::to_string(rayscan::kMaxImageSide) + "]";
  EXPECT_NE(render.out.find("Image width " + side), std::string::npos) << render.out;
  EXPECT_NE(render.out.find("Image height " + side), std::string::npos) << render.out;
  const auto r = rayscan_cli("render " + quoted(data_file("las/point-color.las")) + " --exposure 31");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: --exposure: expected a finite number in [-30, 30], got '31' (see --help)\n");
}
