//! tfs-regress (skeleton; being written).
