//! Photon mapping (Jensen 1996, 2001) and stochastic progressive photon
//! mapping (Hachisuka and Jensen 2009).

pub mod map;

pub use map::{Nearest, Photon, PhotonMap};
