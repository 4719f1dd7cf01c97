//! Procedural heart-valve leaflets (filled below).
