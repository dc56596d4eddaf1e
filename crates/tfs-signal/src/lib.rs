//! tfs-signal (skeleton; being written).
