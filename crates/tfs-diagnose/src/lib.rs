//! tfs-diagnose (being written).
