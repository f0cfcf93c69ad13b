//! Expectation–maximisation for similitude IFSs (Bloem & de Rooij). Work in progress.
