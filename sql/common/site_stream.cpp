// open_site (rayscan/sql/site_stream.hpp): the points of an import in Morton order, chunk by chunk,
// from an index file (built on the fly from the clouds when none is given) or, for scalar fields
// the index does not store, from the clouds read whole.
#include "rayscan/sql/site_stream.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/point_reader.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <optional>
#include <stdexcept>

namespace rayscan::sql {

namespace {

namespace fs = std::filesystem;

// A column of the points table filled from an attribute section of an index file.
enum class Stored { intensity, classification, gps_time, red, green, blue };

// The attributes an index file stores (IndexBuildOptions::attributes).
constexpr io::Attribute kIndexAttributes[] = {io::Attribute::rgb, io::Attribute::intensity,
                                              io::Attribute::classification, io::Attribute::gps_time};

// The stored attribute an --attributes word names (the names are io::AttributeSet's own), if any.
std::optional<io::Attribute> stored_attribute(const std::string& name) {
  for (io::Attribute a : kIndexAttributes)
    if (io::AttributeSet::none().add(a).to_string() == name) return a;
  return std::nullopt;
}

// ---- the index file path ------------------------------------------------------------------------

class IndexSite final : public SiteStream {
 public:
  IndexSite(io::MappedIndex index, std::vector<std::string> given_paths, const ImportOptions& options)
      : m_(std::move(index)), chunk_size_(options.chunk_size) {
    const auto& src = m_.sources();
    for (std::size_t i = 0; i < src.size(); ++i) {
      SourceRow row;
      row.path = i < given_paths.size() ? given_paths[i] : src[i].path;
      row.points = src[i].points;
      row.crs_wkt = m_.crs_wkt();
      sources_.push_back(std::move(row));
      first_ids_.push_back(src[i].first_id);
    }
    for (const std::string& name : options.attributes) {
      const std::optional<io::Attribute> a = stored_attribute(name);
      if (!a) throw std::invalid_argument("attribute '" + name + "': index files store only intensity, "
                                          "classification, gps_time and rgb");
      if (!m_.attributes().has(*a))
        throw std::invalid_argument(m_.path().string() + ": attribute '" + name +
                                    "' requested but the index file does not store it (rebuild it "
                                    "with rayscan index --attributes " + name + ")");
      if (*a == io::Attribute::rgb) {
        for (Stored s : {Stored::red, Stored::green, Stored::blue}) kinds_.push_back(s);
        cols_.push_back({"red", true});
        cols_.push_back({"green", true});
        cols_.push_back({"blue", true});
      } else {
        kinds_.push_back(*a == io::Attribute::intensity        ? Stored::intensity
                         : *a == io::Attribute::classification ? Stored::classification
                                                               : Stored::gps_time);
        cols_.push_back({name, *a != io::Attribute::gps_time});
      }
    }
  }

  const std::vector<SourceRow>& sources() const override { return sources_; }
  const std::vector<ColumnInfo>& columns() const override { return cols_; }

  bool next(ChunkRows& out) override {
    const std::uint64_t n = m_.positions().size();
    if (next_slot_ >= n) return false;
    const std::uint64_t b = next_slot_, e = std::min<std::uint64_t>(n, b + chunk_size_);
    const std::size_t count = static_cast<std::size_t>(e - b);
    out.chunk = next_chunk_++;
    out.first_row = b;
    out.box = AABB();
    out.positions.assign(m_.positions().begin() + static_cast<std::ptrdiff_t>(b),
                         m_.positions().begin() + static_cast<std::ptrdiff_t>(e));
    for (const Vec3& p : out.positions) out.box.expand(p);
    out.refs.resize(count);
    const IdView ids = m_.ids();
    for (std::size_t r = 0; r < count; ++r) {
      const std::uint64_t id = ids[b + r];
      // The source whose id range holds id (sources are in id order).
      const auto it = std::upper_bound(first_ids_.begin(), first_ids_.end(), id);
      const std::size_t s = static_cast<std::size_t>(it - first_ids_.begin()) - 1;
      if (it == first_ids_.begin() || id - first_ids_[s] >= sources_[s].points)
        throw io::IndexError(m_.path().string() + ": section ids, point " + std::to_string(b + r) +
                             ": id " + std::to_string(id) + " is outside every source's id range");
      out.refs[r] = {static_cast<std::uint32_t>(s), id - first_ids_[s]};
    }
    out.values.resize(kinds_.size() * count);
    for (std::size_t c = 0; c < kinds_.size(); ++c) {
      double* v = out.values.data() + c * count;
      for (std::size_t r = 0; r < count; ++r) {
        const std::size_t slot = static_cast<std::size_t>(b + r);
        switch (kinds_[c]) {
          case Stored::intensity: v[r] = m_.intensity()[slot]; break;
          case Stored::classification: v[r] = m_.classification()[slot]; break;
          case Stored::gps_time: v[r] = m_.gps_time()[slot]; break;
          case Stored::red: v[r] = m_.rgb()[slot].r; break;
          case Stored::green: v[r] = m_.rgb()[slot].g; break;
          case Stored::blue: v[r] = m_.rgb()[slot].b; break;
        }
      }
    }
    next_slot_ = e;
    return true;
  }

 private:
  io::MappedIndex m_;
  std::uint32_t chunk_size_;
  std::vector<SourceRow> sources_;
  std::vector<ColumnInfo> cols_;
  std::vector<Stored> kinds_;
  std::vector<std::uint64_t> first_ids_;
  std::uint64_t next_slot_ = 0, next_chunk_ = 0;
};

// ---- the clouds read whole (scalar fields) ------------------------------------------------------

class MemorySite final : public SiteStream {
 public:
  MemorySite(const std::vector<fs::path>& paths, const ImportOptions& options) : chunk_size_(options.chunk_size) {
    for (const auto& p : paths) clouds_.push_back(io::read_point_cloud(p, io::ReadOptions{.scalars = true}));
    attrs_ = resolve_attributes(options.attributes, paths, clouds_);
    for (const auto& a : attrs_) cols_.push_back({a.name, a.integer});
    for (std::size_t i = 0; i < paths.size(); ++i)
      sources_.push_back({paths[i].string(), clouds_[i].size(), clouds_[i].crs_wkt});
    std::vector<const PointCloud*> ptrs;
    for (const auto& c : clouds_) ptrs.push_back(&c);
    layout_ = make_chunk_layout(ptrs, chunk_size_);
  }
  const std::vector<SourceRow>& sources() const override { return sources_; }
  const std::vector<ColumnInfo>& columns() const override { return cols_; }

  bool next(ChunkRows& out) override {
    if (next_ >= layout_.chunks.size()) return false;
    const Chunk& c = layout_.chunks[next_];
    out.chunk = next_++;
    out.first_row = c.first;
    out.box = c.box;
    out.positions.resize(c.count);
    out.refs.resize(c.count);
    out.values.resize(attrs_.size() * c.count);
    for (std::size_t r = 0; r < c.count; ++r) {
      const PointRef ref = layout_.order[c.first + r];
      const PointCloud& cloud = clouds_[ref.source];
      out.refs[r] = ref;
      out.positions[r] = cloud.positions[ref.index];
      for (std::size_t a = 0; a < attrs_.size(); ++a) out.values[a * c.count + r] = attrs_[a].value(cloud, ref.index);
    }
    return true;
  }

 private:
  std::uint32_t chunk_size_;
  std::vector<PointCloud> clouds_;
  std::vector<AttributeColumn> attrs_;
  std::vector<ColumnInfo> cols_;
  std::vector<SourceRow> sources_;
  ChunkLayout layout_;
  std::size_t next_ = 0;
};

}  // namespace

std::unique_ptr<SiteStream> open_site(const std::vector<fs::path>& paths, const ImportOptions& options,
                                      const fs::path& output) {
  if (paths.empty()) throw std::invalid_argument("no input cloud given");
  if (options.chunk_size == 0) throw OptionError({option("chunk_size"), " must be at least 1 point"});
  check_attribute_names(options.attributes, options.pcpatch);  // (both paths below: no column twice)
  bool all_stored = true;
  io::AttributeSet wanted = io::AttributeSet::none();
  for (const std::string& a : options.attributes) {
    if (const auto s = stored_attribute(a)) wanted.add(*s);
    else all_stored = false;
  }
  const bool one_index = paths.size() == 1 && io::is_index_file(paths[0]);
  if (!all_stored) {
    if (one_index)
      throw std::invalid_argument(paths[0].string() + ": index files store only intensity, "
                                  "classification, gps_time and rgb; import the clouds for other fields");
    return std::make_unique<MemorySite>(paths, options);
  }
  for (const auto& p : paths)
    if (io::is_index_file(p) && !one_index)
      throw std::invalid_argument(p.string() + ": an index file must be the only input of an import");
  if (one_index)
    return std::make_unique<IndexSite>(io::MappedIndex::open(paths[0]), std::vector<std::string>{}, options);

  // Every input must have the requested attributes (the index would silently leave one out).
  for (const auto& p : paths) {
    const auto reader = io::open_point_reader(p, wanted, io::ReadOptions{.scalars = false});
    for (const std::string& a : options.attributes)
      if (!reader->attributes().has(*stored_attribute(a)))
        throw std::invalid_argument(p.string() + ": attribute '" + a + "' requested but the file has none");
  }
  // The clouds go through a temporary index file: the external Morton sort of `rayscan index`
  // (bounded memory), then its positions section in storage order are the rows. The file is
  // unlinked as soon as it is mapped, so nothing is left behind whatever happens afterwards.
  static std::atomic<unsigned> counter{0};
  const fs::path dir = options.temp_dir.empty() ? fs::temp_directory_path() : options.temp_dir;
  const fs::path temp = dir / (".rayscan-import-" + std::to_string(::getpid()) + "-" +
                               std::to_string(counter.fetch_add(1)) + ".rsi");
  io::IndexBuildOptions build;
  build.attributes = wanted;
  build.attributes.add(io::Attribute::id);  // the rows name each point's source and number in it
  build.memory_bytes = options.memory_bytes;
  build.temp_dir = dir;
  // The build's own bookkeeping is not the import's: its "spacing" phase (the sampled spacing
  // estimate, counted in samples) is not a phase of the import, and its "done" would end the
  // report before the rows are inserted (ImportOptions::progress).
  if (options.progress)
    build.progress = [progress = options.progress](const char* phase, std::uint64_t done, std::uint64_t total) {
      if (std::strcmp(phase, "spacing") != 0 && std::strcmp(phase, "done") != 0) progress(phase, done, total);
    };
  std::optional<io::MappedIndex> index;
  {
    // Removed once mapped, or when the build fails, or by a signal; a full disk names the
    // import's output.
    const IntermediateFile index_file(temp, output);
    (void)io::build_index_file(paths, temp, build);
    io::IndexOpenOptions open;
    open.verify = io::IndexOpenOptions::Verify::metadata_only;  // just written by us
    index.emplace(io::MappedIndex::open(temp, open));
  }
  std::vector<std::string> given;
  for (const auto& p : paths) given.push_back(p.string());
  return std::make_unique<IndexSite>(std::move(*index), std::move(given), options);
}

}  // namespace rayscan::sql
