//! Reading the references written by `refs/` (see `refs/README.md`).
