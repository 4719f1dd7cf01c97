//! OBJ reading and writing (filled below).
