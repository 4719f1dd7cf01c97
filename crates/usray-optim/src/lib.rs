//! usray-optim: placeholder, filled by its issue.
