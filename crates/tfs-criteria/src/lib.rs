//! tfs-criteria (skeleton; being written).
