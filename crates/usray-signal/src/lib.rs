//! usray-signal: image formation with adjoints and channel-data I/O (work in progress: issue 4).
pub mod channels;
pub use channels::{ChannelData, ChannelMeta, ProbeMeta, TransmitMeta};
