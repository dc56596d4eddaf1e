//! tfs-library (skeleton; being written).
