//! tfs-refine (being written).
