//! tfs-origami (skeleton; being written).
