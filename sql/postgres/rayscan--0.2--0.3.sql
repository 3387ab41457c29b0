-- rayscan 0.2 -> 0.3: a description (COMMENT) on every object of the extension, for \dT+, \df+,
-- \do+ and the object browsers of pgAdmin and QGIS: what it is, its units and the paper
-- section it follows (Teuscher et al., "Ray Queries On Raw Point Clouds", section 4.2), in the words
-- of docs/sql.md. It sets the description of every object, those of 0.1 too, so that all of them
-- are here and read alike. tests/sql/test_postgres.cpp fails for a member of the extension
-- (pg_depend) without a description.
\echo Use "ALTER EXTENSION rayscan UPDATE" to load this file. \quit

-- Types.
COMMENT ON TYPE rs_box IS 'Axis-aligned box (xmin,ymin,zmin,xmax,ymax,zmax), six finite float8 in world units with min <= max: a chunk, patch or point key of the GiST class rs_box_ops (bounds evaluation, paper section 4.2)';
COMMENT ON TYPE rs_ray IS 'Ray predicate dist_ray <= r AND t_min <= ray_time <= t_max, text (ox,oy,oz,dx,dy,dz,r,t_min,t_max) in world units (infinite r or t = no bound); made by ray_within, the right side of && and <-> on rs_box (paper section 4.2, eq. 5)';
COMMENT ON TYPE rs_plane IS 'Half-space dist_plane(p0, n, p) <= 0, text (px,py,pz,nx,ny,nz): a point in world units and a normal of any non-zero length; made by plane_below, the right side of && on rs_box (paper section 4.2, eq. 6)';

-- The paper's scalar functions and their bounds evaluation.
COMMENT ON FUNCTION dist_ray(float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Orthogonal distance of (x,y,z) to the line through o with direction d, world units (paper section 4.2, eq. 5); d need not be unit';
COMMENT ON FUNCTION ray_time(float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 't of the projection of (x,y,z) on the ray, world units along the unit direction, the t column of rayscan query (paper section 4.2, eq. 2)';
COMMENT ON FUNCTION dist_plane(float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Signed distance of (x,y,z) to the plane through p with normal n, world units, positive on the normal side (paper section 4.2, eq. 6)';
COMMENT ON FUNCTION dist_ray_min(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of dist_ray over the box (xmin..zmax), world units: its minimum, lowered by a rounding allowance of about 1e-9 of the distance scale so that it never exceeds dist_ray at a point of the box (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION dist_ray_max(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of dist_ray over the box (xmin..zmax), world units: its maximum, raised by a rounding allowance of about 1e-9 of the distance scale so that it is never below dist_ray at a point of the box (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION ray_time_min(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of ray_time over the box (xmin..zmax), world units: the low end of the eq. 4 interval, lowered by a rounding allowance of about 1e-9 of the distance scale so that it never exceeds ray_time at a point of the box (paper section 4.2)';
COMMENT ON FUNCTION ray_time_max(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of ray_time over the box (xmin..zmax), world units: the high end of the eq. 4 interval, raised by a rounding allowance of about 1e-9 of the distance scale so that it is never below ray_time at a point of the box (paper section 4.2)';
COMMENT ON FUNCTION dist_plane_min(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of dist_plane over the box (xmin..zmax), world units: its minimum, lowered by a rounding allowance of about 1e-9 of the distance scale so that it never exceeds dist_plane at a point of the box (paper section 4.2, eq. 6)';
COMMENT ON FUNCTION dist_plane_max(float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'Bounds evaluation of dist_plane over the box (xmin..zmax), world units: its maximum, raised by a rounding allowance of about 1e-9 of the distance scale so that it is never below dist_plane at a point of the box (paper section 4.2, eq. 6)';

-- Constructors.
COMMENT ON FUNCTION rs_box(float8, float8, float8, float8, float8, float8) IS 'The box (xmin,ymin,zmin,xmax,ymax,zmax), world units, finite with min <= max on every axis: the key of a chunk or patch GiST index (paper section 4.2)';
COMMENT ON FUNCTION rs_box(float8, float8, float8) IS 'The point (x,y,z), world units, as a one-point box: the key of a points-table GiST index, CREATE INDEX ... USING gist (rs_box(x, y, z)) (paper section 4.2)';
COMMENT ON FUNCTION ray_within(float8, float8, float8, float8, float8, float8, float8) IS 'The ray predicate dist_ray <= r (world units) for box && ray_within(...) and the kNN order box <-> ray_within(...); a NULL r is no bound, NULL when a ray argument is NULL (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION ray_within(float8, float8, float8, float8, float8, float8, float8, float8, float8) IS 'The ray predicate dist_ray <= r AND t_min <= ray_time <= t_max (world units) for box && ray_within(...); a NULL r, t_min or t_max is no bound, NULL when a ray argument is NULL (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION plane_below(float8, float8, float8, float8, float8, float8) IS 'The half-space dist_plane(p, n, .) <= 0 (p in world units, n non-zero) for box && plane_below(...); a frustum is an AND of one per plane (paper section 4.2, eq. 6)';
COMMENT ON FUNCTION ray_dwithin(rs_box, float8, float8, float8, float8, float8, float8, float8) IS 'dist_ray(o, d, p) <= r (world units) for a point box, dist_ray_min over the box <= r otherwise; index-pruned on an rs_box_ops GiST index through its planner support function (paper section 4.2, eq. 5)';

-- Text and binary forms.
COMMENT ON FUNCTION rs_box_in(cstring) IS 'Text input of rs_box, (xmin,ymin,zmin,xmax,ymax,zmax) in world units; refuses NaN, infinities and min > max (paper section 4.2)';
COMMENT ON FUNCTION rs_box_out(rs_box) IS 'Text output of rs_box, (xmin,ymin,zmin,xmax,ymax,zmax) in world units, each as float8 prints it (paper section 4.2)';
COMMENT ON FUNCTION rs_box_recv(internal) IS 'Binary input of rs_box: six float8 in network byte order, 48 bytes, world units; refuses another size, NaN, infinities and min > max (paper section 4.2)';
COMMENT ON FUNCTION rs_box_send(rs_box) IS 'Binary output of rs_box: six float8 in network byte order, 48 bytes, world units, as float8 sends them (paper section 4.2)';
COMMENT ON FUNCTION rs_ray_in(cstring) IS 'Text input of rs_ray, (ox,oy,oz,dx,dy,dz,r,t_min,t_max) in world units; the direction under the rule of ray_within (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_ray_out(rs_ray) IS 'Text output of rs_ray, (ox,oy,oz,dx,dy,dz,r,t_min,t_max) in world units, Infinity for no bound (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_plane_in(cstring) IS 'Text input of rs_plane, (px,py,pz,nx,ny,nz): a point in world units and a finite non-zero normal (paper section 4.2, eq. 6)';
COMMENT ON FUNCTION rs_plane_out(rs_plane) IS 'Text output of rs_plane, (px,py,pz,nx,ny,nz): a point in world units and the normal as given (paper section 4.2, eq. 6)';

-- Operators and their functions.
COMMENT ON OPERATOR && (rs_box, rs_ray) IS 'May a point of the box satisfy the ray predicate: the bounds evaluation of dist_ray and ray_time with rounding allowance, world units; GiST strategy 1 of rs_box_ops (paper section 4.2)';
COMMENT ON FUNCTION rs_box_admits(rs_box, rs_ray) IS 'The && operator of rs_box and rs_ray: may a point of the box satisfy the ray predicate (bounds evaluation with rounding allowance, world units; paper section 4.2)';
COMMENT ON OPERATOR && (rs_box, rs_plane) IS 'May a point of the box lie in the half-space plane_below(...): the bounds evaluation of dist_plane, world units; GiST strategy 3 of rs_box_ops (paper section 4.2, eq. 6)';
COMMENT ON FUNCTION rs_box_admits_plane(rs_box, rs_plane) IS 'The && operator of rs_box and rs_plane: may a point of the box lie in the half-space (bounds evaluation of dist_plane, world units; paper section 4.2, eq. 6)';
COMMENT ON OPERATOR <-> (rs_box, rs_ray) IS 'dist_ray of a one-point box, else a lower bound of dist_ray over the box, world units: the kNN order ORDER BY box <-> ray_within(...) (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_box_distance(rs_box, rs_ray) IS 'The <-> operator of rs_box and rs_ray: dist_ray of a one-point box, else a lower bound of dist_ray over the box, world units (paper section 4.2, eq. 5)';
COMMENT ON OPERATOR = (rs_box, rs_box) IS 'The same six coordinates, compared as float8 (so -0 = 0), for DISTINCT, GROUP BY, UNION and joins; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_eq(rs_box, rs_box) IS 'The = operator of rs_box: the same six coordinates, compared as float8 (so -0 = 0); rayscan''s own, not in the paper';
COMMENT ON OPERATOR < (rs_box, rs_box) IS 'Lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, for sorting and grouping, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_lt(rs_box, rs_box) IS 'The < operator of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON OPERATOR <= (rs_box, rs_box) IS 'Lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, for sorting and grouping, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_le(rs_box, rs_box) IS 'The <= operator of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON OPERATOR >= (rs_box, rs_box) IS 'Lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, for sorting and grouping, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_ge(rs_box, rs_box) IS 'The >= operator of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON OPERATOR > (rs_box, rs_box) IS 'Lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, for sorting and grouping, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_gt(rs_box, rs_box) IS 'The > operator of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_cmp(rs_box, rs_box) IS 'B-tree comparison of rs_box (-1, 0, 1): lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) as float8, for sorting and grouping, not a spatial relation; rayscan''s own, not in the paper';
COMMENT ON FUNCTION rs_box_hash(rs_box) IS 'Hash of rs_box for hash joins and hashed grouping, equal for boxes that = calls equal (-0 hashed as 0); rayscan''s own, not in the paper';

-- Index support.
COMMENT ON FUNCTION rs_ray_dwithin_support(internal) IS 'Planner support function of ray_dwithin: derives the index condition box && ray_within(o, d, r) on an rs_box_ops GiST index, as PostGIS does for ST_DWithin (paper section 4.2)';
COMMENT ON FUNCTION rs_gist_consistent(internal, rs_ray, int2, oid, internal) IS 'GiST consistent method of rs_box_ops: the bounds evaluation of && for rs_ray and rs_plane, exact at the leaves (no recheck) (paper section 4.2)';
COMMENT ON FUNCTION rs_gist_distance(internal, rs_ray, int2, oid, internal) IS 'GiST distance method of rs_box_ops for <->: dist_ray of a point key, a lower bound of dist_ray over a page box, world units (paper section 4.2, eq. 5)';
COMMENT ON FUNCTION rs_gist_union(internal, internal) IS 'GiST union method of rs_box_ops: the smallest box holding the entries, world units (paper section 4.2)';
COMMENT ON FUNCTION rs_gist_penalty(internal, internal, internal) IS 'GiST penalty method of rs_box_ops: how much the box grows, as volume plus edge sum (world units^3 + world units), to take the new entry (paper section 4.2)';
COMMENT ON FUNCTION rs_gist_picksplit(internal, internal) IS 'GiST split method of rs_box_ops: halves a page at the median of the box centres along the axis of largest spread, world units (paper section 4.2)';
COMMENT ON FUNCTION rs_gist_same(rs_box, rs_box, internal) IS 'GiST same method of rs_box_ops: whether two keys are the same box (paper section 4.2)';

-- Operator classes and the operator families CREATE OPERATOR CLASS made for them.
COMMENT ON OPERATOR CLASS rs_box_ops USING gist IS 'Default GiST class of rs_box: && rs_ray (1), && rs_plane (3) and ORDER BY <-> rs_ray (15), answered by the bounds evaluation, world units (paper section 4.2)';
COMMENT ON OPERATOR FAMILY rs_box_ops USING gist IS 'GiST family of rs_box: && rs_ray, && rs_plane and <-> rs_ray by bounds evaluation, world units (paper section 4.2)';
COMMENT ON OPERATOR CLASS rs_box_btree_ops USING btree IS 'Default B-tree class of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax) for DISTINCT, GROUP BY, ORDER BY box and merge joins; rayscan''s own, not in the paper';
COMMENT ON OPERATOR FAMILY rs_box_btree_ops USING btree IS 'B-tree family of rs_box: lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax); rayscan''s own, not in the paper';
COMMENT ON OPERATOR CLASS rs_box_hash_ops USING hash IS 'Default hash class of rs_box: = for hashed DISTINCT, GROUP BY and hash joins; rayscan''s own, not in the paper';
COMMENT ON OPERATOR FAMILY rs_box_hash_ops USING hash IS 'Hash family of rs_box: = with rs_box_hash; rayscan''s own, not in the paper';
