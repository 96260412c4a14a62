//! Parameter checks shared by the models' parameter structs: each library struct owns its
//! defaults and a `validate()` returning an [`InvalidParameter`] that names the field, the
//! value and the allowed range with its unit; the command line prefixes the field with its
//! config table (`contact.margin`) and reports it.

/// A parameter outside what its model allows.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{name} = {problem}")]
pub struct InvalidParameter {
    /// The field, as the struct (or a config file) names it.
    pub name: String,
    /// What is wrong with its value: "0.7 is outside the allowed range (0, 0.5] (rod lengths)".
    pub problem: String,
}

impl InvalidParameter {
    /// The same error with the field named inside `table` (`margin` -> `contact.margin`).
    pub fn in_table(mut self, table: &str) -> Self {
        self.name = format!("{table}.{}", self.name);
        self
    }

    /// The same error with the field renamed (a config key that differs from the struct's).
    pub fn renamed(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }
}

/// A number for a message: plain, or in exponent form when it is small (`1e-10`, not
/// `0.0000000001`).
pub fn compact(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-4 {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Check `lo < v <= hi` (`lo_open`) or `lo <= v <= hi`, and that `v` is finite.
pub fn check_range(
    name: &str,
    v: f64,
    lo: f64,
    hi: f64,
    lo_open: bool,
    unit: &str,
) -> Result<(), InvalidParameter> {
    let ok = v.is_finite() && (if lo_open { v > lo } else { v >= lo }) && v <= hi;
    if ok {
        return Ok(());
    }
    let l = if lo_open { "(" } else { "[" };
    Err(InvalidParameter {
        name: name.to_string(),
        problem: format!(
            "{} is outside the allowed range {l}{}, {}] ({unit})",
            compact(v),
            compact(lo),
            compact(hi)
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::check_range;

    #[test]
    fn messages_name_field_value_range_and_unit() {
        assert!(check_range("a", 0.5, 0.0, 1.0, true, "l").is_ok());
        let e = check_range("margin", 0.0, 0.0, 1.0, true, "rod lengths").unwrap_err();
        assert_eq!(
            e.in_table("contact").to_string(),
            "contact.margin = 0 is outside the allowed range (0, 1] (rod lengths)"
        );
        let e = check_range("tol", 1e-20, 1e-14, 0.1, false, "relative").unwrap_err();
        assert_eq!(
            e.to_string(),
            "tol = 1e-20 is outside the allowed range [1e-14, 0.1] (relative)"
        );
        assert!(check_range("x", f64::NAN, 0.0, 1.0, false, "").is_err());
    }
}
