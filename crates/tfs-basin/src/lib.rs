//! tfs-basin (skeleton; being written).
