//! Operations on images and fields that several stages share, above the backends: Gaussian
//! pyramids, label regions and distance maps, composed fields, the target's coverage, fold repair, the inverse field, similarity
//! measures (per-cell SSD, correlation, Dice, local correlation), and moving points with a field.

pub mod compose;
pub mod coverage;
pub mod fold_repair;
pub mod inverse;
pub mod metric;
pub mod points;
pub mod pyramid;
pub mod regions;
pub mod similarity;
pub mod unfold;
