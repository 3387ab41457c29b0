// The ray-query job (rayscan/io/query_job.hpp).
#include "rayscan/io/query_job.hpp"

#include "rayscan/batch.hpp"
#include "rayscan/io/rays.hpp"
#include "rayscan/threads.hpp"

#include <tbb/task_arena.h>

#include <chrono>
#include <cstdio>

namespace rayscan::io {

QueryJobResult run_query(const QueryJobOptions& o) {
  o.query.validate();
  QueryJobResult r;
  // Rays first: a malformed rays file is reported before a large cloud is read.
  r.rays = o.rays.empty() && !o.rays_file.empty() ? read_rays(o.rays_file) : o.rays;
  const auto t0 = std::chrono::steady_clock::now();
  if (!o.cloud) r.cloud = read_point_cloud(o.cloud_file, ReadOptions{.scalars = false});
  const PointCloud& cloud = o.cloud ? *o.cloud : r.cloud;
  char buf[256];
  std::snprintf(buf, sizeof buf, "read %zu points and %zu rays in %.2f s", cloud.size(), r.rays.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  o.control.info(buf);
  const AnyIndex index = make_index(cloud.positions, o.index);
  tbb::task_arena arena(static_cast<int>(resolve_threads(o.control.threads)));
  arena.execute([&] {
    r.hits = std::visit([&](const auto& idx) { return ray_query_batch(idx, r.rays, o.query); }, index);
  });
  return r;
}

void write_hits_csv(std::ostream& os, std::span<const Vec3> positions,
                    const std::vector<std::vector<RayHit>>& hits) {
  const auto precision = os.precision(17);
  os << "ray,rank,index,x,y,z,t,distance\n";
  for (std::size_t r = 0; r < hits.size(); ++r)
    for (std::size_t k = 0; k < hits[r].size(); ++k) {
      const RayHit& h = hits[r][k];
      const Vec3& p = positions[h.index];
      os << r << ',' << k << ',' << h.index << ',' << p.x << ',' << p.y << ',' << p.z << ',' << h.t << ','
         << h.distance << '\n';
    }
  os.precision(precision);
}

}  // namespace rayscan::io
