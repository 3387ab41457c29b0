// IdView: the original point id of each storage slot of a SpatialIndex, either stored (a span of
// uint32 ids) or implied (the identity over N slots: an index file built without its ids section,
// docs/index-format.md "Ids").
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rayscan {

/// Index of a point in the caller's original PointCloud order (max 2^32 - 1 points).
using PointIndex = std::uint32_t;

/// The original PointIndex of each slot of an index, read through `operator[](slot)` and `size()`:
/// either a span of stored ids (the in-memory indexes, an index file with its ids section; the
/// span must outlive the view) or the identity over `size()` slots (an index file built without
/// ids: slot s is point s, i.e. outputs are in index order). A small value type (pointer + size),
/// cheap to copy; it never allocates, so no consumer materialises N ids to fake the identity.
/// Implicitly constructible from `std::span<const PointIndex>` so that indexes returning spans
/// satisfy the SpatialIndex concept's `ids()` requirement unchanged.
class IdView {
 public:
  /// An empty view (no slot).
  constexpr IdView() = default;
  /// The stored ids `ids` (ids[slot] = original id).
  constexpr IdView(std::span<const PointIndex> ids) : data_(ids.data()), size_(ids.size()) {}  // NOLINT(implicit)
  /// The identity over `n` slots: view[s] == s.
  [[nodiscard]] static constexpr IdView identity(std::size_t n) {
    IdView v;
    v.size_ = n;
    return v;
  }
  /// Called by a checked view with (`context`, slot) when the id stored at `slot` is not below
  /// size(); must throw (it never returns normally).
  using BadIdHandler = void (*)(const void* context, std::size_t slot);
  /// Stored ids that are checked when read: every id read through operator[] is compared with
  /// size(), and an id >= size() calls `on_bad(context, slot)`, which throws. For ids from an
  /// unverified file (rayscan::io::MappedIndex): a consumer indexes per-point arrays by id, so
  /// each read is checked (one predictable compare) instead of a pass over all N ids up front.
  [[nodiscard]] static constexpr IdView checked(std::span<const PointIndex> ids, BadIdHandler on_bad,
                                                const void* context) {
    IdView v(ids);
    v.on_bad_ = on_bad;
    v.context_ = context;
    return v;
  }
  /// The original id of slot `slot` (< size(); the slot is not checked; the id is, on a checked
  /// view: an id >= size() throws through the view's handler).
  [[nodiscard]] constexpr PointIndex operator[](std::size_t slot) const {
    if (data_ == nullptr) return static_cast<PointIndex>(slot);
    const PointIndex v = data_[slot];
    if (on_bad_ != nullptr && v >= size_) [[unlikely]]
      on_bad_(context_, slot);
    return v;
  }
  /// Appends the ids of slots [begin, end) (end <= size()) to `out`, in slot order: one copy of
  /// the stored ids, a count for the identity, each id checked on a checked view (which throws
  /// through its handler, `out` then holding a prefix of them). Bulk form of operator[] for
  /// queries that take a whole node or subtree (box_query).
  void append_to(std::vector<PointIndex>& out, std::size_t begin, std::size_t end) const {
    if (data_ == nullptr) {
      for (std::size_t s = begin; s < end; ++s) out.push_back(static_cast<PointIndex>(s));
    } else if (on_bad_ == nullptr) {
      out.insert(out.end(), data_ + begin, data_ + end);
    } else {
      for (std::size_t s = begin; s < end; ++s) out.push_back((*this)[s]);
    }
  }
  /// Replaces each of the n local slot numbers v[j] (slots base + v[j] < size(), as a SIMD box
  /// test writes them) by that slot's id, in place: v[j] = (*this)[base + v[j]]. Checked as
  /// operator[] on a checked view (a bad id throws, v then partly mapped).
  void map_slots(PointIndex* v, std::size_t n, std::size_t base) const {
    if (data_ == nullptr) {
      for (std::size_t j = 0; j < n; ++j) v[j] = static_cast<PointIndex>(base + v[j]);
    } else if (on_bad_ == nullptr) {
      const PointIndex* d = data_ + base;
      for (std::size_t j = 0; j < n; ++j) v[j] = d[v[j]];
    } else {
      for (std::size_t j = 0; j < n; ++j) v[j] = (*this)[base + v[j]];
    }
  }
  /// Number of slots.
  [[nodiscard]] constexpr std::size_t size() const { return size_; }
  /// True when no slot.
  [[nodiscard]] constexpr bool empty() const { return size_ == 0; }
  /// True when the ids are implied (slot s is point s); then data() is null. A view of N > 0
  /// stored ids is never the identity, even when they happen to equal their slots.
  [[nodiscard]] constexpr bool is_identity() const { return data_ == nullptr && size_ > 0; }
  /// The stored ids (null for the identity or an empty view). Raw: not checked, even on a
  /// checked view (read through operator[] where the ids may be untrusted).
  [[nodiscard]] constexpr const PointIndex* data() const { return data_; }
  /// data() where reading them needs no check, else nullptr (the identity, or a checked
  /// view): for kernels that move ids with their points (box_query).
  [[nodiscard]] constexpr const PointIndex* unchecked_data() const { return on_bad_ == nullptr ? data_ : nullptr; }

 private:
  const PointIndex* data_ = nullptr;
  std::size_t size_ = 0;
  BadIdHandler on_bad_ = nullptr;  ///< set on a checked view
  const void* context_ = nullptr;
};

}  // namespace rayscan
