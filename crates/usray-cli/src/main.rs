//! The `usray` binary.
fn main() {}
