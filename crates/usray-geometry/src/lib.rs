//! usray-geometry: placeholder, filled by its issue.
