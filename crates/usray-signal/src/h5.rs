//! What the MAT v7.3 reader ([`crate::mat73`]) and the UFF reader and writer
//! ([`crate::uff`]) share on top of the HDF5 library (the `hdf5-metno` crate,
//! linking the system `libhdf5`): string attributes in any of the encodings MATLAB,
//! h5py and USTB write, numeric datasets read as `f64` within a value budget, and
//! the creation of an HDF5 file in place of another, atomically.

use std::path::Path;

use hdf5::types::{FixedAscii, FixedUnicode, TypeDescriptor, VarLenAscii, VarLenUnicode};

use crate::error::{Result, SignalError};

/// A reader's error before the file is named ([`SignalError::format`] names it).
pub(crate) type R<T> = std::result::Result<T, String>;

/// The longest fixed-length string attribute read in full (MATLAB class names,
/// UFF class names and names are far shorter).
const MAX_FIXED_STRING: usize = 1024;

/// The string attribute `name` of `loc`: a scalar or the first element of a
/// one-element array, fixed- or variable-length, ASCII or UTF-8 (MATLAB writes
/// fixed-length ASCII, h5py variable-length UTF-8). `None` when absent or not a
/// string.
pub(crate) fn string_attr(loc: &hdf5::Location, name: &str) -> Option<String> {
    let attr = loc.attr(name).ok()?;
    let first = |v: Vec<String>| v.into_iter().next();
    match attr.dtype().ok()?.to_descriptor().ok()? {
        TypeDescriptor::VarLenUnicode => first(
            attr.read_raw::<VarLenUnicode>()
                .ok()?
                .iter()
                .map(|s| s.as_str().to_owned())
                .collect(),
        ),
        TypeDescriptor::VarLenAscii => first(
            attr.read_raw::<VarLenAscii>()
                .ok()?
                .iter()
                .map(|s| s.as_str().to_owned())
                .collect(),
        ),
        TypeDescriptor::FixedAscii(_) => first(
            attr.read_raw::<FixedAscii<MAX_FIXED_STRING>>()
                .ok()?
                .iter()
                .map(|s| s.as_str().to_owned())
                .collect(),
        ),
        TypeDescriptor::FixedUnicode(_) => first(
            attr.read_raw::<FixedUnicode<MAX_FIXED_STRING>>()
                .ok()?
                .iter()
                .map(|s| s.as_str().to_owned())
                .collect(),
        ),
        _ => None,
    }
}

/// The numeric attribute `name` of `loc` as `f64` values (`None` when absent or
/// not numeric).
pub(crate) fn numeric_attr(loc: &hdf5::Location, name: &str) -> Option<Vec<f64>> {
    loc.attr(name).ok()?.read_raw::<f64>().ok()
}

/// The number of values in an HDF5 `shape`, or an error naming `what` when the
/// product overflows.
pub(crate) fn element_count(shape: &[usize], what: &str) -> R<usize> {
    shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| format!("{what} has shape {shape:?}: too many elements"))
}

/// Every value of the numeric dataset `ds` as `f64` (HDF5 converts integers and
/// `single` exactly), in the dataset's C order. The caller checks the count
/// ([`element_count`]) against its limit first. `what` names the dataset in errors.
pub(crate) fn read_f64(ds: &hdf5::Dataset, what: &str) -> R<Vec<f64>> {
    ds.read_raw::<f64>()
        .map_err(|e| format!("{what} cannot be read as numbers: {e}"))
}

/// Creates the HDF5 file `path` atomically: `write` fills a new HDF5 file at a
/// temporary path beside `path` (the library opens files by name), which is
/// closed, synced and renamed onto `path` only if `write` succeeded; on any error
/// `path` is untouched (as [`crate::write_atomic`] does for byte writers).
pub(crate) fn create_atomic<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&hdf5::File) -> hdf5::Result<()>,
{
    let tmp = crate::io::temp_beside(path)?;
    let wrote = hdf5::File::create(tmp.path()).and_then(|file| {
        write(&file)?;
        file.close()
    });
    wrote.map_err(|e| SignalError::format(path, format!("writing HDF5: {e}")))?;
    crate::io::persist(tmp, path)
}
