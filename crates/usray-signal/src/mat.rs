//! A small MATLAB v5 `.mat` reader (numeric, char, struct and cell arrays; zlib
//! `miCOMPRESSED` elements). [`crate::import`] turns what it reads into CONTRACT §2
//! channel data.
//!
//! Format: MathWorks, "MAT-File Format" (R2023b), chapter 1 "Level 5 MAT-files":
//! 128-byte header, then data elements `(type u32, nbytes u32, data, pad to 8)`,
//! or the small form `(nbytes u16 << 16 | type u16, 4 data bytes)`. Every numeric
//! class is converted to `f64` (integers exactly; `uint8` metadata such as
//! `Nelements` cannot overflow afterwards). Opaque class objects (MATLAB `classdef`
//! instances) and sparse arrays are recognised and skipped.
//!
//! MAT v7.3 files (HDF5) are read by the private `mat73` module into the same [`MatFile`];
//! [`read_mat`] chooses by the header.
//!
//! Why a hand-written v5 reader: the Rust crates for `.mat` files read numeric
//! arrays only — `matfile` (0.5, "alpha quality", cell and structure arrays not
//! implemented) and `mat5` (0.1, dense and sparse numeric arrays) — while the
//! Verasonics layout is a struct (`param`) and full-matrix capture a cell
//! (`data{k}`).

use std::io::Read;
use std::path::Path;

use crate::error::{Result, SignalError};

/// What a `.mat` file may make the reader do, checked before the work: a hostile
/// or corrupt file (a decompression bomb, cells nested a million deep) gets an
/// error naming the limit instead of exhausting memory or the stack.
pub mod limits {
    /// Largest file read, bytes (256 MiB).
    pub const MAX_FILE_BYTES: u64 = 256 << 20;
    /// Largest inflated size of one compressed element, bytes (256 MiB).
    pub const MAX_INFLATED_BYTES: u64 = 256 << 20;
    /// Most numbers (and characters) held from one file: 32 Mi values, 256 MiB as
    /// `f64`.
    pub const MAX_VALUES: usize = 32 << 20;
    /// Deepest nesting of cells and structs.
    pub const MAX_NESTING: usize = 32;
}

/// The MATLAB class a numeric array was stored in: the values are converted to
/// `f64` exactly, but an importer needs the class to state how integer samples
/// were offset (an unsigned type centred at mid-range is a common export).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumericClass {
    /// `double`.
    Double,
    /// `single`.
    Single,
    /// `int8`.
    Int8,
    /// `uint8`.
    UInt8,
    /// `int16`.
    Int16,
    /// `uint16`.
    UInt16,
    /// `int32`.
    Int32,
    /// `uint32`.
    UInt32,
    /// `int64`.
    Int64,
    /// `uint64`.
    UInt64,
    /// `logical`.
    Logical,
}

impl NumericClass {
    /// The class of MAT v5 array-class number `class` (6–15), `None` for others.
    pub fn from_mat_class(class: u8) -> Option<NumericClass> {
        use NumericClass::*;
        Some(match class {
            6 => Double,
            7 => Single,
            8 => Int8,
            9 => UInt8,
            10 => Int16,
            11 => UInt16,
            12 => Int32,
            13 => UInt32,
            14 => Int64,
            15 => UInt64,
            _ => return None,
        })
    }
    /// The class from its MATLAB name (`"double"`, `"uint8"`, …), as MAT v7.3
    /// files store it in the `MATLAB_class` attribute.
    pub fn from_name(name: &str) -> Option<NumericClass> {
        use NumericClass::*;
        Some(match name {
            "double" => Double,
            "single" => Single,
            "int8" => Int8,
            "uint8" => UInt8,
            "int16" => Int16,
            "uint16" => UInt16,
            "int32" => Int32,
            "uint32" => UInt32,
            "int64" => Int64,
            "uint64" => UInt64,
            "logical" => Logical,
            _ => return None,
        })
    }
    /// The MATLAB name of the class.
    pub fn name(self) -> &'static str {
        use NumericClass::*;
        match self {
            Double => "double",
            Single => "single",
            Int8 => "int8",
            UInt8 => "uint8",
            Int16 => "int16",
            UInt16 => "uint16",
            Int32 => "int32",
            UInt32 => "uint32",
            Int64 => "int64",
            UInt64 => "uint64",
            Logical => "logical",
        }
    }
    /// The value range of an integer class, `None` for floating point and logical.
    pub fn integer_range(self) -> Option<(f64, f64)> {
        use NumericClass::*;
        Some(match self {
            Int8 => (i8::MIN as f64, i8::MAX as f64),
            UInt8 => (0.0, u8::MAX as f64),
            Int16 => (i16::MIN as f64, i16::MAX as f64),
            UInt16 => (0.0, u16::MAX as f64),
            Int32 => (i32::MIN as f64, i32::MAX as f64),
            UInt32 => (0.0, u32::MAX as f64),
            Int64 => (i64::MIN as f64, i64::MAX as f64),
            UInt64 => (0.0, u64::MAX as f64),
            Double | Single | Logical => return None,
        })
    }
}

/// A MATLAB value.
#[derive(Clone, Debug, PartialEq)]
pub enum MatValue {
    /// A numeric or logical array, column-major, converted to `f64`.
    Numeric {
        /// The class the file stored the numbers in (they are held as `f64`).
        class: NumericClass,
        /// MATLAB dimensions.
        dims: Vec<usize>,
        /// Real part, column-major.
        re: Vec<f64>,
        /// Imaginary part for complex arrays.
        im: Option<Vec<f64>>,
    },
    /// A character array (as one string, column-major order).
    Char(String),
    /// A struct array: field names and, per element (column-major), one value per field.
    Struct {
        /// MATLAB dimensions.
        dims: Vec<usize>,
        /// Field names.
        fields: Vec<String>,
        /// `elems[i][f]`: field `f` of element `i`.
        elems: Vec<Vec<MatValue>>,
    },
    /// A cell array, column-major.
    Cell {
        /// MATLAB dimensions.
        dims: Vec<usize>,
        /// The cells.
        cells: Vec<MatValue>,
    },
    /// A class this reader does not decode (the MATLAB class number).
    Unsupported(u8),
}

impl MatValue {
    /// The field `name` of a 1×1 struct.
    pub fn field(&self, name: &str) -> Option<&MatValue> {
        match self {
            MatValue::Struct { fields, elems, .. } if elems.len() == 1 => {
                fields.iter().position(|f| f == name).map(|i| &elems[0][i])
            }
            _ => None,
        }
    }
    /// The value of a numeric scalar.
    pub fn scalar(&self) -> Option<f64> {
        match self {
            MatValue::Numeric { re, .. } if re.len() == 1 => Some(re[0]),
            _ => None,
        }
    }
}

/// Named variables of a `.mat` file, in file order.
pub type MatFile = Vec<(String, MatValue)>;

struct Cur<'a> {
    b: &'a [u8],
    p: usize,
}

type R<T> = std::result::Result<T, String>;

impl<'a> Cur<'a> {
    fn u32(&mut self) -> R<u32> {
        let s = self
            .b
            .get(self.p..self.p + 4)
            .ok_or("unexpected end of data")?;
        self.p += 4;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    /// Read one element tag; returns (type, bytes, whole element consumed incl. padding).
    fn element(&mut self) -> R<(u32, &'a [u8])> {
        let first = self.u32()?;
        if first >> 16 != 0 {
            let (ty, n) = (first & 0xffff, (first >> 16) as usize);
            if n > 4 {
                return Err(format!("small data element claims {n} bytes"));
            }
            let s = self
                .b
                .get(self.p..self.p + 4)
                .ok_or("truncated small element")?;
            self.p += 4;
            return Ok((ty, &s[..n]));
        }
        let n = self.u32()? as usize;
        let end = self.p.checked_add(n).ok_or("element size overflow")?;
        let s = self
            .b
            .get(self.p..end)
            .ok_or_else(|| format!("element of {n} bytes runs past the end of the data"))?;
        self.p = if first == 15 {
            end
        } else {
            end.div_ceil(8) * 8
        };
        Ok((first, s))
    }
}

fn numbers(ty: u32, s: &[u8]) -> R<Vec<f64>> {
    macro_rules! conv {
        ($t:ty, $w:expr) => {
            s.chunks_exact($w)
                .map(|c| <$t>::from_le_bytes(c.try_into().unwrap_or([0; $w])) as f64)
                .collect()
        };
    }
    Ok(match ty {
        1 => s.iter().map(|&v| v as i8 as f64).collect(),
        2 => s.iter().map(|&v| v as f64).collect(),
        3 => conv!(i16, 2),
        4 => conv!(u16, 2),
        5 => conv!(i32, 4),
        6 => conv!(u32, 4),
        7 => conv!(f32, 4),
        9 => conv!(f64, 8),
        12 => conv!(i64, 8),
        13 => conv!(u64, 8),
        _ => return Err(format!("numeric data of MAT type {ty} not supported")),
    })
}

/// How many values the file may still make the reader hold
/// ([`limits::MAX_VALUES`] in all).
pub(crate) struct Budget {
    pub(crate) values_left: usize,
}

impl Budget {
    pub(crate) fn take(&mut self, n: usize, name: &str) -> R<()> {
        self.values_left = self.values_left.checked_sub(n).ok_or_else(|| {
            format!(
                "array `{name}` takes the file past {} values (usray_signal::mat::limits::MAX_VALUES)",
                limits::MAX_VALUES
            )
        })?;
        Ok(())
    }
}

/// One `miMATRIX` element, `depth` levels inside cells and structs.
fn parse_matrix(body: &[u8], depth: usize, budget: &mut Budget) -> R<(String, MatValue)> {
    if depth > limits::MAX_NESTING {
        return Err(format!(
            "cells or structs nested deeper than {} levels (usray_signal::mat::limits::MAX_NESTING)",
            limits::MAX_NESTING
        ));
    }
    if body.is_empty() {
        return Ok((
            String::new(),
            MatValue::Numeric {
                class: NumericClass::Double,
                dims: vec![0, 0],
                re: vec![],
                im: None,
            },
        ));
    }
    let mut c = Cur { b: body, p: 0 };
    let (_, flags) = c.element()?;
    if flags.len() < 8 {
        return Err("array flags too short".into());
    }
    let class = flags[0];
    let complex = flags[1] & 0x08 != 0;
    let logical = flags[1] & 0x02 != 0;
    if class == 17 || class == 3 || class == 5 {
        return Ok((String::new(), MatValue::Unsupported(class)));
    }
    let (dty, d) = c.element()?;
    let dims: Vec<usize> = numbers(dty, d)?
        .into_iter()
        .map(|v| v.max(0.0) as usize)
        .collect();
    let (_, name) = c.element()?;
    let name = String::from_utf8_lossy(name).into_owned();
    let count = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| format!("array `{name}` has dimensions {dims:?}: too many elements"))?;
    // Every element takes at least one byte of the remaining data (cells and struct
    // fields at least an 8-byte tag), so a larger count is a corrupt header; checking
    // it here keeps a bad file from requesting a huge allocation.
    if count > body.len().saturating_sub(c.p).max(1) * 8 {
        return Err(format!(
            "array `{name}` claims dimensions {dims:?} ({count} elements) but only {} bytes follow",
            body.len().saturating_sub(c.p)
        ));
    }
    let value = match class {
        1 => {
            let mut cells = Vec::with_capacity(count);
            for _ in 0..count {
                let (ty, s) = c.element()?;
                if ty != 14 {
                    return Err(format!("cell element has type {ty}, expected miMATRIX"));
                }
                cells.push(parse_matrix(s, depth + 1, budget)?.1);
            }
            MatValue::Cell { dims, cells }
        }
        2 => {
            let (lt, l) = c.element()?;
            let len = *numbers(lt, l)?.first().ok_or("missing field-name length")? as usize;
            let (_, names) = c.element()?;
            if len == 0 {
                return Err("field-name length 0".into());
            }
            let fields: Vec<String> = names
                .chunks(len)
                .map(|ch| {
                    String::from_utf8_lossy(ch.split(|&b| b == 0).next().unwrap_or(&[]))
                        .into_owned()
                })
                .collect();
            let mut elems = Vec::with_capacity(count);
            for _ in 0..count {
                let mut vals = Vec::with_capacity(fields.len());
                for _ in 0..fields.len() {
                    let (ty, s) = c.element()?;
                    if ty != 14 {
                        return Err(format!("struct field has type {ty}, expected miMATRIX"));
                    }
                    vals.push(parse_matrix(s, depth + 1, budget)?.1);
                }
                elems.push(vals);
            }
            MatValue::Struct {
                dims,
                fields,
                elems,
            }
        }
        4 => {
            let (ty, s) = c.element()?;
            budget.take(s.len(), &name)?;
            let chars: String = match ty {
                16 | 1 | 2 => String::from_utf8_lossy(s).into_owned(),
                _ => numbers(ty, s)?
                    .into_iter()
                    .filter_map(|v| char::from_u32(v as u32))
                    .collect(),
            };
            MatValue::Char(chars)
        }
        6..=15 => {
            budget.take(count * if complex { 2 } else { 1 }, &name)?;
            let (ty, s) = c.element()?;
            let re = numbers(ty, s)?;
            let im = if complex {
                let (ty, s) = c.element()?;
                Some(numbers(ty, s)?)
            } else {
                None
            };
            if re.len() != count {
                return Err(format!(
                    "array `{name}` holds {} values, its dimensions {dims:?} need {count}",
                    re.len()
                ));
            }
            let class = if logical {
                NumericClass::Logical
            } else {
                NumericClass::from_mat_class(class).unwrap_or(NumericClass::Double)
            };
            MatValue::Numeric {
                class,
                dims,
                re,
                im,
            }
        }
        other => MatValue::Unsupported(other),
    };
    Ok((name, value))
}

/// Read every variable of a MATLAB `.mat` file: v5 (and v6, v7) by the reader
/// here, v7.3 (HDF5) by the private `mat73` module, chosen by the header.
pub fn read_mat(path: impl AsRef<Path>) -> Result<MatFile> {
    let path = path.as_ref();
    let size = std::fs::metadata(path)
        .map_err(|e| SignalError::io(path, e))?
        .len();
    if size > limits::MAX_FILE_BYTES {
        return Err(SignalError::format(
            path,
            format!(
                "{size} bytes is past the limit of {} (usray_signal::mat::limits::MAX_FILE_BYTES)",
                limits::MAX_FILE_BYTES
            ),
        ));
    }
    if crate::mat73::is_mat73(path)? {
        return crate::mat73::read_mat73(path);
    }
    let bytes = std::fs::read(path).map_err(|e| SignalError::io(path, e))?;
    parse_mat(&bytes).map_err(|w| SignalError::format(path, w))
}

/// Parse the bytes of a MATLAB v5 `.mat` file.
pub fn parse_mat(bytes: &[u8]) -> std::result::Result<MatFile, String> {
    if bytes.len() < 128 {
        return Err("too short for a MAT v5 header (128 bytes)".into());
    }
    if bytes.starts_with(b"\x89HDF") || bytes[..128].windows(9).any(|w| w == b"MATLAB 7.3") {
        return Err(
            "MAT v7.3 (HDF5) cannot be parsed from bytes; read the file with read_mat".into(),
        );
    }
    if &bytes[126..128] != b"IM" {
        return Err("not a little-endian MAT v5 file (header endian indicator is not 'IM')".into());
    }
    let mut out = Vec::new();
    let mut budget = Budget {
        values_left: limits::MAX_VALUES,
    };
    let mut c = Cur {
        b: &bytes[128..],
        p: 0,
    };
    while c.p + 8 <= c.b.len() {
        let (ty, s) = c.element()?;
        let inflated;
        let (ty, s) = if ty == 15 {
            let mut d = Vec::new();
            flate2::read::ZlibDecoder::new(s)
                .take(limits::MAX_INFLATED_BYTES + 1)
                .read_to_end(&mut d)
                .map_err(|e| format!("corrupt miCOMPRESSED element: {e}"))?;
            if d.len() as u64 > limits::MAX_INFLATED_BYTES {
                return Err(format!(
                    "a compressed element inflates past {} bytes (usray_signal::mat::limits::MAX_INFLATED_BYTES)",
                    limits::MAX_INFLATED_BYTES
                ));
            }
            inflated = d;
            let mut ic = Cur { b: &inflated, p: 0 };
            let (t, s) = ic.element()?;
            (t, s)
        } else {
            (ty, s)
        };
        if ty == 14 {
            let (name, v) = parse_matrix(s, 0, &mut budget)?;
            out.push((name, v));
        }
    }
    Ok(out)
}
