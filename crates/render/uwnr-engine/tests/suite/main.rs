//! Integration tests of `uwnr-engine`: the whole generator against the plain reference, on
//! every instruction set this CPU supports, at small widths and several sizes.

mod network;
