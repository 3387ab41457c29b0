-- rayscan 0.1: paper section 4.2 (Teuscher et al., "Ray Queries On Raw Point Clouds").
\echo Use "CREATE EXTENSION rayscan" to load this file. \quit

CREATE FUNCTION dist_ray(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, x float8, y float8, z float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_ray'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_ray(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, x float8, y float8, z float8) IS 'Orthogonal distance of (x,y,z) to the ray line (paper eq. 5); d need not be unit';
CREATE FUNCTION ray_time(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, x float8, y float8, z float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_ray_time'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION ray_time(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, x float8, y float8, z float8) IS 't of the projection of (x,y,z) on the ray, world units along the unit direction (as rayscan query)';
CREATE FUNCTION dist_plane(px float8, py float8, pz float8, nx float8, ny float8, nz float8, x float8, y float8, z float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_plane'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_plane(px float8, py float8, pz float8, nx float8, ny float8, nz float8, x float8, y float8, z float8) IS 'Signed distance of (x,y,z) to the plane (paper eq. 6), positive on the normal side';
CREATE FUNCTION dist_ray_min(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_ray_min'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_ray_min(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the minimum of dist_ray over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it never exceeds dist_ray at every point of the box';
CREATE FUNCTION dist_ray_max(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_ray_max'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_ray_max(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the maximum of dist_ray over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it is never below dist_ray at every point of the box';
CREATE FUNCTION ray_time_min(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_ray_time_min'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION ray_time_min(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the minimum of ray_time over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it never exceeds ray_time at every point of the box';
CREATE FUNCTION ray_time_max(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_ray_time_max'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION ray_time_max(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the maximum of ray_time over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it is never below ray_time at every point of the box';
CREATE FUNCTION dist_plane_min(px float8, py float8, pz float8, nx float8, ny float8, nz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_plane_min'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_plane_min(px float8, py float8, pz float8, nx float8, ny float8, nz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the minimum of dist_plane over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it never exceeds dist_plane at every point of the box';
CREATE FUNCTION dist_plane_max(px float8, py float8, pz float8, nx float8, ny float8, nz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS float8
  AS 'MODULE_PATHNAME', 'rs_dist_plane_max'
  LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION dist_plane_max(px float8, py float8, pz float8, nx float8, ny float8, nz float8, xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) IS 'Bounds evaluation (section 4.2): the maximum of dist_plane over the box, widened by a rounding allowance (about 1e-9 of the distance scale) so that it is never below dist_plane at every point of the box';

-- Chunk box (xmin,ymin,zmin,xmax,ymax,zmax), float8.
CREATE TYPE rs_box;
CREATE FUNCTION rs_box_in(cstring) RETURNS rs_box AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_out(rs_box) RETURNS cstring AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE TYPE rs_box (INPUT = rs_box_in, OUTPUT = rs_box_out, INTERNALLENGTH = 48, ALIGNMENT = double);
CREATE FUNCTION rs_box(xmin float8, ymin float8, zmin float8, xmax float8, ymax float8, zmax float8) RETURNS rs_box
  AS 'MODULE_PATHNAME', 'rs_box_make' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION rs_box(float8, float8, float8, float8, float8, float8) IS 'Axis-aligned box (world units; finite, min <= max on every axis), the key of a chunk or patch GiST index';

-- Ray predicate: dist_ray <= r AND t_min <= ray_time <= t_max.
CREATE TYPE rs_ray;
CREATE FUNCTION rs_ray_in(cstring) RETURNS rs_ray AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_ray_out(rs_ray) RETURNS cstring AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE TYPE rs_ray (INPUT = rs_ray_in, OUTPUT = rs_ray_out, INTERNALLENGTH = 72, ALIGNMENT = double);
CREATE FUNCTION ray_within(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, r float8) RETURNS rs_ray
  AS 'MODULE_PATHNAME', 'rs_ray_make' LANGUAGE C IMMUTABLE PARALLEL SAFE;
CREATE FUNCTION ray_within(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, r float8, t_min float8, t_max float8) RETURNS rs_ray
  AS 'MODULE_PATHNAME', 'rs_ray_make' LANGUAGE C IMMUTABLE PARALLEL SAFE;
COMMENT ON FUNCTION ray_within(float8, float8, float8, float8, float8, float8, float8) IS 'The ray predicate dist_ray <= r (world units) for box && ray_within(...) and the kNN order box <-> ray_within(...); a NULL r is no bound; NULL when a ray argument is NULL';
COMMENT ON FUNCTION ray_within(float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'The ray predicate dist_ray <= r AND t_min <= ray_time <= t_max (world units); a NULL r, t_min or t_max is no bound; NULL when a ray argument is NULL';

CREATE FUNCTION rs_box_admits(rs_box, rs_ray) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_distance(rs_box, rs_ray) RETURNS float8 AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE OPERATOR && (LEFTARG = rs_box, RIGHTARG = rs_ray, FUNCTION = rs_box_admits, RESTRICT = areasel, JOIN = areajoinsel);
CREATE OPERATOR <-> (LEFTARG = rs_box, RIGHTARG = rs_ray, FUNCTION = rs_box_distance);

-- rs_box(x,y,z): the point as a degenerate box, the key of a points-table GiST index:
--   CREATE INDEX ON points USING gist (rs_box(x, y, z));
CREATE FUNCTION rs_box(x float8, y float8, z float8) RETURNS rs_box
  AS 'MODULE_PATHNAME', 'rs_point_box' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION rs_box(float8, float8, float8) IS 'The point (x,y,z) as a one-point box, the key of a points-table GiST index';
COMMENT ON FUNCTION rs_box_admits(rs_box, rs_ray) IS 'The && operator: may a point of the box satisfy the ray predicate (bounds evaluation, with rounding allowance)';
COMMENT ON FUNCTION rs_box_distance(rs_box, rs_ray) IS 'The <-> operator: dist_ray of a one-point box, else a lower bound of dist_ray over the box';

-- Half-space dist_plane(p, n, .) <= 0 (eq. 6); a frustum is an AND of  box && plane_below(...).
CREATE TYPE rs_plane;
CREATE FUNCTION rs_plane_in(cstring) RETURNS rs_plane AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_plane_out(rs_plane) RETURNS cstring AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE TYPE rs_plane (INPUT = rs_plane_in, OUTPUT = rs_plane_out, INTERNALLENGTH = 48, ALIGNMENT = double);
CREATE FUNCTION plane_below(px float8, py float8, pz float8, nx float8, ny float8, nz float8) RETURNS rs_plane
  AS 'MODULE_PATHNAME', 'rs_plane_make' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION plane_below(float8, float8, float8, float8, float8, float8) IS 'Half-space {p : dist_plane(p0, n, p) <= 0} (paper eq. 6), for box && plane_below(...)';
CREATE FUNCTION rs_box_admits_plane(rs_box, rs_plane) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE OPERATOR && (LEFTARG = rs_box, RIGHTARG = rs_plane, FUNCTION = rs_box_admits_plane, RESTRICT = areasel, JOIN = areajoinsel);
COMMENT ON FUNCTION rs_box_admits_plane(rs_box, rs_plane) IS 'The && operator of a half-space: may a point of the box lie in plane_below(...)';

-- ray_dwithin(box, o, d, r): dist_ray <= r for a point box, dist_ray_min <= r for a chunk box;
-- its planner support function derives  box && ray_within(o, d, r)  on a GiST rs_box_ops index
-- (the PostGIS ST_DWithin pattern), so  WHERE ray_dwithin(rs_box(x,y,z), o..., d..., r)  is
-- exact and index-pruned without a hand-written bounds clause.
CREATE FUNCTION rs_ray_dwithin_support(internal) RETURNS internal AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION ray_dwithin(b rs_box, ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, r float8) RETURNS bool
  AS 'MODULE_PATHNAME', 'rs_ray_dwithin' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE SUPPORT rs_ray_dwithin_support;
COMMENT ON FUNCTION ray_dwithin(rs_box, float8, float8, float8, float8, float8, float8, float8) IS 'dist_ray(o,d,p) <= r for a point box, dist_ray_min over the box <= r otherwise (section 4.2); index-pruned through its support function';

CREATE FUNCTION rs_gist_consistent(internal, rs_ray, int2, oid, internal) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_gist_distance(internal, rs_ray, int2, oid, internal) RETURNS float8 AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_gist_union(internal, internal) RETURNS rs_box AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_gist_penalty(internal, internal, internal) RETURNS internal AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_gist_picksplit(internal, internal) RETURNS internal AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_gist_same(rs_box, rs_box, internal) RETURNS internal AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;

CREATE OPERATOR CLASS rs_box_ops DEFAULT FOR TYPE rs_box USING gist AS
  OPERATOR 1 && (rs_box, rs_ray),
  OPERATOR 3 && (rs_box, rs_plane),
  OPERATOR 15 <-> (rs_box, rs_ray) FOR ORDER BY pg_catalog.float_ops,
  FUNCTION 1 rs_gist_consistent(internal, rs_ray, int2, oid, internal),
  FUNCTION 2 rs_gist_union(internal, internal),
  FUNCTION 5 rs_gist_penalty(internal, internal, internal),
  FUNCTION 6 rs_gist_picksplit(internal, internal),
  FUNCTION 7 rs_gist_same(rs_box, rs_box, internal),
  FUNCTION 8 rs_gist_distance(internal, rs_ray, int2, oid, internal);
