//! Free-field (geometric) transfer functions from a geometry and a grid.
