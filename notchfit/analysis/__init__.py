"""Fits and judgements: shapes, fitting, the estimation core, identify and diagnosis; returns objects, writes nothing."""
