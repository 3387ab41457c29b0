-- rayscan 0.4 -> 0.5: statistics of rs_box. ANALYZE keeps, besides the standard statistics, a
-- sample of the boxes of every rs_box column and of every rs_box expression an index or CREATE
-- STATISTICS covers (rs_box(x, y, z)); ray_dwithin's planner support function estimates the
-- fraction of rows it keeps as the fraction of that sample it holds for, instead of areasel's
-- constant 0.005 (which it still takes where there is no sample: ANALYZE it once after this update).
\echo Use "ALTER EXTENSION rayscan UPDATE" to load this file. \quit

CREATE FUNCTION rs_box_analyze(internal) RETURNS bool AS 'MODULE_PATHNAME' LANGUAGE C STRICT PARALLEL SAFE;
ALTER TYPE rs_box SET (ANALYZE = rs_box_analyze);
COMMENT ON FUNCTION rs_box_analyze(internal) IS 'ANALYZE support of rs_box: the standard statistics plus a sample of the boxes (world units), from which ray_dwithin''s planner support function estimates its selectivity (rayscan''s own, not in the paper)';
COMMENT ON FUNCTION rs_ray_dwithin_support(internal) IS 'Planner support function of ray_dwithin: derives the index condition box && ray_dwithin_ray(o, d, r) on an rs_box_ops GiST index, as PostGIS does for ST_DWithin (paper section 4.2), and estimates its selectivity from the box sample rs_box_analyze keeps';
