//! tfs-plot (skeleton; being written).
