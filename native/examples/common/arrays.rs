//! The raw little-endian arrays the benchmark scripts' `--save-arrays` write (`*.f32`: three
//! floats a point, `*.u32`: three indices a triangle), read by the timing examples.

/// Triples of little-endian u32 (triangles), or of f32 bits (see [`points`]).
pub fn read(path: &str) -> Vec<[u32; 3]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    bytes.chunks_exact(12).map(|c| std::array::from_fn(|i| u32::from_le_bytes(c[4 * i..4 * i + 4].try_into().unwrap()))).collect()
}

/// Triples of little-endian f32 (points, deltas).
pub fn points(path: &str) -> Vec<[f32; 3]> {
    read(path).into_iter().map(|p| p.map(f32::from_bits)).collect()
}
