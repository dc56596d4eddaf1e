//! tfs (skeleton; being written).
