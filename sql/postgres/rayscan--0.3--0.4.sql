-- rayscan 0.3 -> 0.4: ray_dwithin_ray, the ray of the index condition that ray_dwithin's planner
-- support function derives (box && ray_dwithin_ray(o, d, r)). It is ray_within(o, d, r) with
-- ray_dwithin's argument checks, so a bad argument fails with ray_dwithin's message whichever plan
-- runs (an index scan evaluates the index condition before ray_dwithin), and STRICT as ray_dwithin
-- is. The text inputs of rs_box, rs_ray and rs_plane refuse a number beyond float8's range as
-- float8 does; their descriptions say so.
\echo Use "ALTER EXTENSION rayscan UPDATE" to load this file. \quit

CREATE FUNCTION ray_dwithin_ray(ox float8, oy float8, oz float8, dx float8, dy float8, dz float8, r float8) RETURNS rs_ray
  AS 'MODULE_PATHNAME', 'rs_ray_dwithin_ray' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
COMMENT ON FUNCTION ray_dwithin_ray(float8, float8, float8, float8, float8, float8, float8) IS 'The ray predicate dist_ray <= r (world units) of the index condition box && ray_dwithin_ray(...) that ray_dwithin''s planner support function derives: ray_within(o, d, r) with ray_dwithin''s argument checks and messages, NULL when an argument is NULL (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_ray_dwithin_support(internal) IS 'Planner support function of ray_dwithin: derives the index condition box && ray_dwithin_ray(o, d, r) on an rs_box_ops GiST index, as PostGIS does for ST_DWithin (paper section 4.2)';
COMMENT ON FUNCTION rs_box_in(cstring) IS 'Text input of rs_box, (xmin,ymin,zmin,xmax,ymax,zmax) in world units; refuses NaN, infinities, min > max (naming the axis) and numbers beyond float8''s range (paper section 4.2)';
COMMENT ON FUNCTION rs_ray_in(cstring) IS 'Text input of rs_ray, (ox,oy,oz,dx,dy,dz,r,t_min,t_max) in world units; the direction under the rule of ray_within, numbers beyond float8''s range refused (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_plane_in(cstring) IS 'Text input of rs_plane, (px,py,pz,nx,ny,nz): a point in world units and a finite non-zero normal, numbers beyond float8''s range refused (paper section 4.2, eq. 6)';
