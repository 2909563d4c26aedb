//! In-process tests of the group (to be written).
