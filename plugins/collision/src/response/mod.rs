//! The response: the contacts' projection, friction and restitution.

pub mod contact;
