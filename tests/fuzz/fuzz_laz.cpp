// libFuzzer target for the LAZ decoder (LASzip VLR, chunk table, pointwise streams, v1, v2 and v3
// items; seeded with a v1 pointwise file, a v2 chunked and a v3 layered one): any input must
// either decode or raise rayscan::io::FormatError; anything else is a bug. Built by run.sh.
// The records of a successfully read PDRF 6-8 file are also sent through the layered (v3)
// encoder and decoded back: the result must equal them byte for byte (and, under UBSan, the
// encoder's arithmetic must not overflow on arbitrary field values).
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"

#include "../../io/src/laz/encoder_v3.hpp"
#include "../../io/src/laz/laz.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

namespace {

void round_trip_layered(const rayscan::io::LasRecords& r) {
  namespace laz = rayscan::io::laz;
  static constexpr std::size_t kCore[3] = {30, 36, 38};
  if (r.pdrf < 6 || r.pdrf > 8 || r.count == 0) return;
  const std::size_t core = kCore[r.pdrf - 6], rec = r.record_length;
  if (rec < core || r.records.size() < rec) return;
  const std::size_t n = std::min<std::size_t>(r.records.size() / rec, 3000);
  laz::LaszipVlr vlr;
  vlr.compressor = 3;
  vlr.chunk_size = static_cast<std::uint32_t>(n);
  vlr.items.push_back({laz::kPoint14, 30, 3});
  if (r.pdrf == 7) vlr.items.push_back({laz::kRgb14, 6, 3});
  if (r.pdrf == 8) vlr.items.push_back({laz::kRgbNir14, 8, 3});
  if (rec > core) vlr.items.push_back({laz::kByte14, static_cast<std::uint16_t>(rec - core), 3});
  std::vector<std::uint8_t> chunk;
  laz::LayeredChunkEncoder enc(r.pdrf, rec - core);
  enc.encode(r.records.data(), n, rec, chunk);
  std::vector<std::uint8_t> back(n * rec);
  laz::ChunkDecoder dec(vlr);
  const rayscan::io::detail::Input in{{chunk.data(), chunk.size()}, "round-trip", {}};
  dec.start(in, 0, laz::Chunk{0, chunk.size(), 0, n}, chunk.size());
  dec.next(n, back.data());
  dec.finish();
  if (std::memcmp(back.data(), r.records.data(), n * rec) != 0) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rayscan::io::LasRecords r;
  try {
    r = rayscan::io::read_las_records({data, size}, "fuzz-input");
  } catch (const rayscan::io::FormatError&) {
    return 0;
  }
  round_trip_layered(r);  // a FormatError here is a bug: not caught
  return 0;
}
