//! tfs-dynamics (skeleton; being written).
