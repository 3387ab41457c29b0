-- rayscan 0.1 -> 0.2: comparison and binary I/O for rs_box (ALTER EXTENSION rayscan UPDATE; a new
-- CREATE EXTENSION runs rayscan--0.1.sql and then this script).
\echo Use "ALTER EXTENSION rayscan UPDATE" to load this file. \quit

-- Binary I/O (COPY ... (FORMAT binary), binary results): six float8 in network byte order; the
-- receiver refuses another size, NaN, infinities and min > max, naming rs_box.
CREATE FUNCTION rs_box_recv(internal) RETURNS rs_box AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_send(rs_box) RETURNS bytea AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
ALTER TYPE rs_box SET (RECEIVE = rs_box_recv, SEND = rs_box_send);

-- Equality (the same six coordinates as float8) with a B-tree and a hash operator class, for
-- SELECT DISTINCT box, GROUP BY box, count(DISTINCT box), UNION, ORDER BY box and joins on boxes.
-- The order is lexicographic on (xmin, ymin, zmin, xmax, ymax, zmax): a total order for sorting
-- and grouping, not a spatial relation.
CREATE FUNCTION rs_box_eq(rs_box, rs_box) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_lt(rs_box, rs_box) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_le(rs_box, rs_box) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_ge(rs_box, rs_box) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_gt(rs_box, rs_box) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_cmp(rs_box, rs_box) RETURNS int4 AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE FUNCTION rs_box_hash(rs_box) RETURNS int4 AS 'MODULE_PATHNAME' LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE;
CREATE OPERATOR = (LEFTARG = rs_box, RIGHTARG = rs_box, FUNCTION = rs_box_eq, COMMUTATOR = =,
                   RESTRICT = eqsel, JOIN = eqjoinsel, HASHES, MERGES);
CREATE OPERATOR < (LEFTARG = rs_box, RIGHTARG = rs_box, FUNCTION = rs_box_lt, COMMUTATOR = >, NEGATOR = >=,
                   RESTRICT = scalarltsel, JOIN = scalarltjoinsel);
CREATE OPERATOR <= (LEFTARG = rs_box, RIGHTARG = rs_box, FUNCTION = rs_box_le, COMMUTATOR = >=, NEGATOR = >,
                    RESTRICT = scalarlesel, JOIN = scalarlejoinsel);
CREATE OPERATOR >= (LEFTARG = rs_box, RIGHTARG = rs_box, FUNCTION = rs_box_ge, COMMUTATOR = <=, NEGATOR = <,
                    RESTRICT = scalargesel, JOIN = scalargejoinsel);
CREATE OPERATOR > (LEFTARG = rs_box, RIGHTARG = rs_box, FUNCTION = rs_box_gt, COMMUTATOR = <, NEGATOR = <=,
                   RESTRICT = scalargtsel, JOIN = scalargtjoinsel);
COMMENT ON FUNCTION rs_box_eq(rs_box, rs_box) IS 'The = operator: the same six coordinates (compared as float8, so -0 = 0)';
COMMENT ON FUNCTION rs_box_cmp(rs_box, rs_box) IS 'Lexicographic order on (xmin,ymin,zmin,xmax,ymax,zmax), for sorting and grouping; not a spatial relation';
CREATE OPERATOR CLASS rs_box_btree_ops DEFAULT FOR TYPE rs_box USING btree AS
  OPERATOR 1 <, OPERATOR 2 <=, OPERATOR 3 =, OPERATOR 4 >=, OPERATOR 5 >,
  FUNCTION 1 rs_box_cmp(rs_box, rs_box);
CREATE OPERATOR CLASS rs_box_hash_ops DEFAULT FOR TYPE rs_box USING hash AS
  OPERATOR 1 = (rs_box, rs_box),
  FUNCTION 1 rs_box_hash(rs_box);
