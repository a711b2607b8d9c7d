//! The file formats the core reads and writes as text or bytes it is handed (it does no I/O, so
//! the browser's build reads them too): classic world files ([`world`], `.w`), scene files
//! ([`scene`], TOML) and closed meshes ([`mesh`], OBJ and STL). Each builds a
//! [`Model`](crate::Model) and a [`State`](crate::State) and reports bad input with its file,
//! line and what was expected. Writing animated glTF is in the `jello-io` crate.

pub mod mesh;
pub mod scene;
pub mod world;
