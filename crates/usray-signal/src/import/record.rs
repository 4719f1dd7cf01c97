//! The record of an import by content: where each quantity came from and what
//! was assumed, written to the output's `source`.

use serde_json::{Map, Value};

use super::quantities::{Params, Quantity};

/// Where each quantity came from and what was assumed: the output's `source`.
pub(super) struct Record<'a> {
    pub params: Params<'a>,
    /// The file's top-level variable names, for messages.
    pub names: Vec<&'a str>,
    pub used: Map<String, Value>,
    pub assumed: Vec<String>,
}

impl<'a> Record<'a> {
    /// `forced` if given (from `flag`), else the file's scalar `q`.
    pub fn lookup(
        &mut self,
        key: &str,
        q: Quantity,
        forced: Option<f64>,
        flag: &str,
    ) -> Result<Option<f64>, String> {
        let found = match forced {
            Some(v) => Some((flag.to_string(), v)),
            None => self.params.scalar(q)?,
        };
        Ok(found.map(|(from, v)| {
            self.used.insert(key.into(), from.into());
            v
        }))
    }

    /// Like [`Record::lookup`], but missing is an error naming what was looked for.
    pub fn required(
        &mut self,
        key: &str,
        q: Quantity,
        forced: Option<f64>,
        flag: &str,
    ) -> Result<f64, String> {
        let where_ = match self.params.struct_name {
            Some(s) => format!("in struct `{s}` or at the top level"),
            None => "at the top level (the file has no struct of acquisition parameters)".into(),
        };
        let names = self.names.clone();
        self.lookup(key, q, forced, flag)?.ok_or_else(|| {
            format!(
                "no {} found: looked {where_} for a field named one of {} (case and underscores ignored; the file holds {names:?}); pass {flag}",
                q.describe(),
                q.looked_for()
            )
        })
    }

    pub fn assume(&mut self, key: &str, what: String) {
        self.used.insert(key.into(), "assumed".into());
        self.assumed.push(what);
    }
}
