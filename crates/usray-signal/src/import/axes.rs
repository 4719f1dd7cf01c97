//! Which axis of an RF array holds what: samples, elements, transmits, frames.
//!
//! Files store RF as `(samples, elements, transmits)` (Verasonics, MUST), as
//! `(transmits, elements, samples)` (C-order exports of the same), with frames
//! appended, or in other orders. The roles are found from the counts the file's
//! parameters give (elements, transmit angles): among the orders consistent with
//! them, the one whose sample axis is the longest, then the one closest to
//! MATLAB's `(samples, elements, transmits, frames)`.

use std::fmt;
use std::str::FromStr;

/// The role of one axis of an RF array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// Fast time.
    Samples,
    /// Receive elements.
    Elements,
    /// Transmits (steering angles) of one acquisition.
    Transmits,
    /// Separate acquisitions, imaged one by one.
    Frames,
}

impl Axis {
    /// Rank in MATLAB's usual order, for preferring it among equal candidates.
    fn rank(self) -> u8 {
        match self {
            Axis::Samples => 0,
            Axis::Elements => 1,
            Axis::Transmits => 2,
            Axis::Frames => 3,
        }
    }
    /// Parses a comma-separated order such as `samples,elements,transmits`.
    pub fn parse_order(text: &str) -> Result<Vec<Axis>, String> {
        text.split(',').map(|s| s.trim().parse()).collect()
    }
}

impl FromStr for Axis {
    type Err = String;
    fn from_str(s: &str) -> Result<Axis, String> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "samples" | "sample" | "time" => Axis::Samples,
            "elements" | "element" | "channels" => Axis::Elements,
            "transmits" | "transmit" | "angles" => Axis::Transmits,
            "frames" | "frame" => Axis::Frames,
            other => {
                return Err(format!(
                    "unknown axis `{other}`: expected samples, elements, transmits (or angles) or frames"
                ))
            }
        })
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::Samples => "samples",
            Axis::Elements => "elements",
            Axis::Transmits => "transmits",
            Axis::Frames => "frames",
        })
    }
}

/// The roles of an array's axes, and a note when other orders fitted as well.
#[derive(Debug, PartialEq)]
pub(super) struct Roles {
    /// One role per axis.
    pub roles: Vec<Axis>,
    /// Set when another order fitted the counts equally well.
    pub ambiguity: Option<String>,
}

/// Roles for an array of dimensions `dims` holding `n_elements` elements (if
/// known) and `n_transmits` transmits (if known; a transmit axis only when > 1).
pub(super) fn assign(
    dims: &[usize],
    n_elements: Option<usize>,
    n_transmits: Option<usize>,
) -> Result<Roles, String> {
    let nd = dims.len();
    let want_transmits = n_transmits.filter(|&n| n > 1);
    let longest = dims.iter().copied().max().unwrap_or(0);
    // (not the longest as samples, inversions against MATLAB's order) per candidate.
    let mut candidates: Vec<((bool, usize), Vec<Axis>)> = Vec::new();
    for s in 0..nd {
        for e in (0..nd).filter(|&e| e != s) {
            if n_elements.is_some_and(|n| dims[e] != n) {
                continue;
            }
            let transmit_axes: Vec<Option<usize>> = match want_transmits {
                None => vec![None],
                Some(n) => (0..nd)
                    .filter(|&t| t != s && t != e && dims[t] == n)
                    .map(Some)
                    .collect(),
            };
            for t in transmit_axes {
                let roles: Vec<Axis> = (0..nd)
                    .map(|k| match k {
                        k if k == s => Axis::Samples,
                        k if k == e => Axis::Elements,
                        k if Some(k) == t => Axis::Transmits,
                        _ => Axis::Frames,
                    })
                    .collect();
                candidates.push(((dims[s] != longest, inversions(&roles)), roles));
            }
        }
    }
    candidates.sort_by_key(|(key, _)| *key);
    let Some((best_key, best)) = candidates.first().cloned() else {
        return Err(format!(
            "no order of its axes holds {} and {}",
            n_elements.map_or("samples and elements".to_string(), |n| format!(
                "{n} elements"
            )),
            want_transmits.map_or("samples".to_string(), |n| format!("{n} transmits"))
        ));
    };
    let rivals = candidates.iter().filter(|(k, _)| k.0 == best_key.0).count() - 1;
    let ambiguity = (rivals > 0).then(|| {
        format!(
            "{rivals} other axis order(s) also fit the counts; took ({}), the closest to MATLAB's (samples, elements, transmits, frames)",
            join(&best)
        )
    });
    Ok(Roles {
        roles: best,
        ambiguity,
    })
}

/// Checks a user-given order against the array and the counts.
pub(super) fn check(
    dims: &[usize],
    roles: &[Axis],
    n_elements: Option<usize>,
    n_transmits: Option<usize>,
) -> Result<(), String> {
    if roles.len() != dims.len() {
        return Err(format!(
            "--axes names {} axes, the array has {} ({dims:?})",
            roles.len(),
            dims.len()
        ));
    }
    for (role, want) in [
        (Axis::Samples, None),
        (Axis::Elements, n_elements),
        (Axis::Transmits, n_transmits),
    ] {
        let at: Vec<usize> = (0..dims.len()).filter(|&k| roles[k] == role).collect();
        match (role, at.as_slice()) {
            (Axis::Transmits, []) if want.is_none_or(|n| n == 1) => {}
            (_, [k]) => {
                if let Some(n) = want.filter(|&n| dims[*k] != n) {
                    return Err(format!(
                        "--axes puts {role} on axis {k} of length {}, but the file gives {n}",
                        dims[*k]
                    ));
                }
            }
            _ => return Err(format!("--axes must name `{role}` exactly once")),
        }
    }
    Ok(())
}

/// Pairs of axes out of MATLAB's order.
fn inversions(roles: &[Axis]) -> usize {
    let mut n = 0;
    for i in 0..roles.len() {
        for j in i + 1..roles.len() {
            n += usize::from(roles[i].rank() > roles[j].rank());
        }
    }
    n
}

/// `samples, elements, transmits`.
pub(super) fn join(roles: &[Axis]) -> String {
    roles
        .iter()
        .map(Axis::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The array (column-major, `dims`) in C order `[frame, transmit, element,
/// sample]`, with `offset` subtracted; returns the samples and the counts
/// `(n_frames, n_transmits, n_elements, n_samples)`. Several frame axes combine
/// with the first varying fastest (MATLAB's linear indexing).
pub(super) fn gather(
    values: &[f64],
    dims: &[usize],
    roles: &[Axis],
    offset: f64,
) -> (Vec<f64>, (usize, usize, usize, usize)) {
    let mut stride = vec![1usize; dims.len()];
    for k in 1..dims.len() {
        stride[k] = stride[k - 1] * dims[k - 1];
    }
    let axis_of = |r: Axis| (0..dims.len()).find(|&k| roles[k] == r);
    let len_stride = |r: Axis| axis_of(r).map_or((1, 0), |k| (dims[k], stride[k]));
    let (ns, ss) = len_stride(Axis::Samples);
    let (ne, se) = len_stride(Axis::Elements);
    let (nt, st) = len_stride(Axis::Transmits);
    let frame_axes: Vec<usize> = (0..dims.len())
        .filter(|&k| roles[k] == Axis::Frames)
        .collect();
    let nf: usize = frame_axes.iter().map(|&k| dims[k]).product();
    let mut out = Vec::with_capacity(nf * nt * ne * ns);
    for f in 0..nf {
        let mut rest = f;
        let mut base = 0;
        for &k in &frame_axes {
            base += (rest % dims[k]) * stride[k];
            rest /= dims[k];
        }
        for t in 0..nt {
            for e in 0..ne {
                let start = base + t * st + e * se;
                out.extend((0..ns).map(|s| values[start + s * ss] - offset));
            }
        }
    }
    (out, (nf, nt, ne, ns))
}

#[cfg(test)]
mod tests {
    use super::*;
    use Axis::*;

    #[test]
    fn roles_follow_the_counts_in_any_order() {
        let r = assign(&[2688, 128, 7], None, Some(7)).unwrap();
        assert_eq!(r.roles, vec![Samples, Elements, Transmits]);
        assert!(r.ambiguity.is_none());
        let r = assign(&[7, 128, 2688], Some(128), Some(7)).unwrap();
        assert_eq!(r.roles, vec![Transmits, Elements, Samples]);
        let r = assign(&[128, 2688, 7], None, Some(7)).unwrap();
        assert_eq!(r.roles, vec![Elements, Samples, Transmits]);
        // No angles: the third axis is frames (PWI_disk).
        let r = assign(&[334, 128, 32], Some(128), None).unwrap();
        assert_eq!(r.roles, vec![Samples, Elements, Frames]);
        // Fewer samples than elements: the element count decides.
        let r = assign(&[100, 128, 3], Some(128), Some(3)).unwrap();
        assert_eq!(r.roles, vec![Samples, Elements, Transmits]);
        // Two axes could be elements: MATLAB's order wins, and it is said.
        let r = assign(&[2688, 128, 7, 128], Some(128), Some(7)).unwrap();
        assert_eq!(r.roles, vec![Samples, Elements, Transmits, Frames]);
        assert!(r.ambiguity.is_some());
        assert!(assign(&[300, 64, 7], Some(128), Some(7)).is_err());
        assert!(assign(&[300, 128, 5], Some(128), Some(7)).is_err());
    }

    #[test]
    fn gather_reorders_column_major_to_c_order() {
        // dims (samples 2, transmits 3, elements 2), column-major: value = s + 2t + 6e.
        let dims = [2, 3, 2];
        let v: Vec<f64> = (0..12).map(f64::from).collect();
        let (out, counts) = gather(&v, &dims, &[Samples, Transmits, Elements], 1.0);
        assert_eq!(counts, (1, 3, 2, 2));
        // out[t][e][s] = s + 2t + 6e - 1
        for t in 0..3 {
            for e in 0..2 {
                for s in 0..2 {
                    assert_eq!(out[(t * 2 + e) * 2 + s], (s + 2 * t + 6 * e) as f64 - 1.0);
                }
            }
        }
    }

    #[test]
    fn a_given_order_is_checked() {
        assert!(check(
            &[10, 4, 3],
            &[Samples, Elements, Transmits],
            Some(4),
            Some(3)
        )
        .is_ok());
        assert!(check(&[10, 4, 3], &[Samples, Elements, Transmits], Some(5), None).is_err());
        assert!(check(&[10, 4, 3], &[Samples, Samples, Transmits], None, None).is_err());
        assert!(check(&[10, 4], &[Samples, Elements, Transmits], None, None).is_err());
        assert!(check(&[10, 4, 3], &[Samples, Elements, Frames], Some(4), None).is_ok());
        assert_eq!(
            Axis::parse_order("samples, elements,angles").unwrap(),
            vec![Samples, Elements, Transmits]
        );
        assert!(Axis::parse_order("samples,x").is_err());
    }
}
