//! tfs-data (skeleton; being written).
