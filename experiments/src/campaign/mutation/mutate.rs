//! Seeded damage to valid files: text (TOML configs and scenes, CSV time series) and HDF5
//! (snapshots, checkpoints), byte-wise and structurally. Each mutation returns the new bytes
//! and a one-line description, so a finding can be reproduced from its seed alone.

use hdf5_pure::{AttrValue, DType, File, FileBuilder};
use rand::RngExt;
use rand::seq::IndexedRandom;
use rand_chacha::ChaCha8Rng;

/// What a mutator produced: the damaged bytes and what was done to them.
#[derive(Debug)]
pub struct Mutated {
    /// The damaged file.
    pub bytes: Vec<u8>,
    /// What was done (`"truncated at byte 812 of 4096"`).
    pub what: String,
}

/// Values that stress a parser or a validator: non-finite, huge, negative, zero, of another
/// type, out of the integer range.
const TEXT_VALUES: [&str; 16] = [
    "nan",
    "inf",
    "-inf",
    "1e308",
    "1e400",
    "-1",
    "0",
    "-0.0",
    "1e12",
    "18446744073709551616",
    "\"x\"",
    "[1, 2]",
    "true",
    "",
    "1e-320",
    "{ a = 1 }",
];

/// Damage a text file (TOML or CSV) in one of eight ways.
pub fn text(seed: &[u8], rng: &mut ChaCha8Rng) -> Mutated {
    let s = String::from_utf8_lossy(seed).into_owned();
    let mut lines: Vec<String> = s.lines().map(str::to_string).collect();
    let csv = !s.contains('=');
    let pick = |rng: &mut ChaCha8Rng, n: usize| rng.random_range(0..n.max(1));
    let kind = rng.random_range(0..8);
    let what = match kind {
        0 => {
            let at = rng.random_range(0..seed.len().max(1));
            return Mutated {
                bytes: seed[..at].to_vec(),
                what: format!("truncated at byte {at} of {}", seed.len()),
            };
        }
        1 => {
            let mut bytes = seed.to_vec();
            let at = pick(rng, bytes.len());
            let bit = rng.random_range(0..8);
            if let Some(b) = bytes.get_mut(at) {
                *b ^= 1 << bit;
            }
            return Mutated {
                bytes,
                what: format!("bit {bit} of byte {at} flipped"),
            };
        }
        2 => {
            let i = pick(rng, lines.len());
            lines.remove(i.min(lines.len().saturating_sub(1)));
            format!("line {} deleted", i + 1)
        }
        3 => {
            let i = pick(rng, lines.len()).min(lines.len().saturating_sub(1));
            let l = lines.get(i).cloned().unwrap_or_default();
            lines.insert(i, l);
            format!("line {} duplicated", i + 1)
        }
        4 if csv => replace_cell(&mut lines, rng),
        4 => replace_value(&mut lines, rng),
        5 => rename_key(&mut lines, rng),
        6 => {
            let (i, j) = (pick(rng, lines.len()), pick(rng, lines.len()));
            if i < lines.len() && j < lines.len() {
                lines.swap(i, j);
            }
            format!("lines {} and {} swapped", i + 1, j + 1)
        }
        _ => {
            let i = pick(rng, lines.len() + 1).min(lines.len());
            let junk = [
                "[", "x = ", "= 1", "[[run]]", "\u{feff}", ",,,", "[motile]", "\"",
            ]
            .choose(rng)
            .copied()
            .unwrap_or("[");
            lines.insert(i, junk.to_string());
            format!("line {} inserted: {junk:?}", i + 1)
        }
    };
    let mut text = lines.join("\n");
    text.push('\n');
    Mutated {
        bytes: text.into_bytes(),
        what,
    }
}

/// A TOML `key = value` line's value replaced by a stressing one.
fn replace_value(lines: &mut [String], rng: &mut ChaCha8Rng) -> String {
    let keyed: Vec<usize> = (0..lines.len())
        .filter(|&i| lines[i].contains('=') && !lines[i].trim_start().starts_with('#'))
        .collect();
    let Some(&i) = keyed.choose(rng) else {
        return "no value to replace".into();
    };
    let v = TEXT_VALUES.choose(rng).copied().unwrap_or("nan");
    let key = lines[i]
        .split('=')
        .next()
        .unwrap_or("")
        .trim_end()
        .to_string();
    lines[i] = format!("{key} = {v}");
    format!("line {}: `{key}` set to `{v}`", i + 1)
}

/// A CSV cell (not in the header) replaced by a stressing value.
fn replace_cell(lines: &mut [String], rng: &mut ChaCha8Rng) -> String {
    if lines.len() < 2 {
        return "no cell to replace".into();
    }
    let i = rng.random_range(1..lines.len());
    let mut cells: Vec<String> = lines[i].split(',').map(str::to_string).collect();
    let c = rng.random_range(0..cells.len());
    let v = [
        "nan", "inf", "-inf", "1e308", "1e400", "-1", "0", "", "x", "--1", "1e-320",
    ]
    .choose(rng)
    .copied()
    .unwrap_or("nan");
    cells[c] = v.to_string();
    lines[i] = cells.join(",");
    format!("line {} column {}: set to `{v}`", i + 1, c + 1)
}

/// A key (TOML) or a column name (CSV header) changed by one character.
fn rename_key(lines: &mut [String], rng: &mut ChaCha8Rng) -> String {
    let Some(i) = (0..lines.len())
        .filter(|&i| !lines[i].trim().is_empty())
        .collect::<Vec<_>>()
        .choose(rng)
        .copied()
    else {
        return "no key to rename".into();
    };
    let mut chars: Vec<char> = lines[i].chars().collect();
    let end = chars
        .iter()
        .position(|&c| c == '=' || c == ',')
        .unwrap_or(chars.len());
    if end == 0 {
        return "no key to rename".into();
    }
    let at = rng.random_range(0..end);
    if rng.random_bool(0.5) {
        chars.remove(at);
    } else {
        chars.insert(at, 'x');
    }
    lines[i] = chars.into_iter().collect();
    format!("line {}: key changed at character {}", i + 1, at + 1)
}

/// Damage an HDF5 file: half the time its bytes (truncation, flipped bits, overwritten
/// windows), half the time its structure, rebuilt with a dataset or attribute dropped,
/// renamed, reshaped, retyped or poisoned with non-finite or huge values.
pub fn hdf5(seed: &[u8], rng: &mut ChaCha8Rng) -> Mutated {
    if rng.random_bool(0.5) {
        return hdf5_bytes(seed, rng);
    }
    let Ok(mut content) = Content::read(seed) else {
        return hdf5_bytes(seed, rng);
    };
    let what = content.mutate(rng);
    match content.build() {
        Ok(bytes) => Mutated { bytes, what },
        Err(e) => Mutated {
            bytes: seed.to_vec(),
            what: format!("{what} (not writable: {e}; unchanged)"),
        },
    }
}

fn hdf5_bytes(seed: &[u8], rng: &mut ChaCha8Rng) -> Mutated {
    let mut bytes = seed.to_vec();
    let n = bytes.len().max(1);
    let what = match rng.random_range(0..4) {
        0 => {
            let at = rng.random_range(0..n);
            bytes.truncate(at);
            format!("truncated at byte {at} of {n}")
        }
        1 => {
            let flips = rng.random_range(1..=4);
            let mut at = Vec::new();
            for _ in 0..flips {
                let i = rng.random_range(0..n);
                if let Some(b) = bytes.get_mut(i) {
                    *b ^= 1 << rng.random_range(0..8);
                }
                at.push(i);
            }
            format!("bits flipped at bytes {at:?}")
        }
        2 => {
            let i = rng.random_range(0..n);
            let fill: u8 = if rng.random_bool(0.5) {
                0xff
            } else {
                rng.random()
            };
            for b in bytes.iter_mut().skip(i).take(8) {
                *b = fill;
            }
            format!("8 bytes at {i} set to {fill:#04x}")
        }
        _ => {
            let i = rng.random_range(0..n);
            for b in bytes.iter_mut().skip(i).take(64) {
                *b = 0;
            }
            format!("64 bytes at {i} zeroed")
        }
    };
    Mutated { bytes, what }
}

/// A dataset of a file being rebuilt: its values as f64 or i64, and its shape.
#[derive(Clone, Debug)]
struct Data {
    name: String,
    floats: Option<Vec<f64>>,
    ints: Vec<i64>,
    shape: Vec<u64>,
}

/// A flat HDF5 file (root attributes and root datasets), as motile writes them, read for
/// editing and written back.
#[derive(Clone, Debug)]
pub struct Content {
    attrs: Vec<(String, AttrValue)>,
    data: Vec<Data>,
}

impl Content {
    /// Read a file's root attributes and datasets.
    pub fn read(bytes: &[u8]) -> Result<Self, hdf5_pure::Error> {
        let file = File::from_bytes(bytes.to_vec())?;
        let mut attrs: Vec<(String, AttrValue)> = file.root().attrs()?.into_iter().collect();
        attrs.sort_by(|a, b| a.0.cmp(&b.0));
        let mut data = Vec::new();
        for name in file.root().datasets()? {
            let d = file.dataset(&name)?;
            let shape = d.shape()?;
            let (floats, ints) = match d.dtype()? {
                DType::F64 | DType::F32 => (Some(d.read_f64()?), Vec::new()),
                _ => (None, d.read_i64()?),
            };
            data.push(Data {
                name,
                floats,
                ints,
                shape,
            });
        }
        Ok(Self { attrs, data })
    }

    /// The file's bytes.
    pub fn build(&self) -> Result<Vec<u8>, hdf5_pure::Error> {
        let mut b = FileBuilder::new();
        for (k, v) in &self.attrs {
            b.set_attr(k, v.clone());
        }
        for d in &self.data {
            let ds = b.create_dataset(&d.name);
            let ds = match &d.floats {
                Some(f) => ds.with_f64_data(f),
                None => ds.with_i64_data(&d.ints),
            };
            ds.with_shape(&d.shape);
        }
        b.finish()
    }

    /// Set element `index` of the float dataset `name` (false if there is none).
    pub fn set_value(&mut self, name: &str, index: usize, v: f64) -> bool {
        let slot = self
            .data
            .iter_mut()
            .find(|d| d.name == name)
            .and_then(|d| d.floats.as_mut())
            .and_then(|f| f.get_mut(index));
        slot.map(|x| *x = v).is_some()
    }

    /// Element `index` of the float dataset `name`.
    pub fn value(&self, name: &str, index: usize) -> Option<f64> {
        let d = self.data.iter().find(|d| d.name == name)?;
        d.floats.as_ref()?.get(index).copied()
    }

    /// Set (or add) the root attribute `name`.
    pub fn set_attr(&mut self, name: &str, v: AttrValue) {
        match self.attrs.iter_mut().find(|a| a.0 == name) {
            Some(a) => a.1 = v,
            None => self.attrs.push((name.to_string(), v)),
        }
    }

    fn mutate(&mut self, rng: &mut ChaCha8Rng) -> String {
        let kinds = if self.data.is_empty() { 2 } else { 9 };
        match rng.random_range(0..kinds) {
            0 => self.drop_attr(rng),
            1 => self.poison_attr(rng),
            2 => {
                let i = rng.random_range(0..self.data.len());
                format!("dataset '{}' dropped", self.data.remove(i).name)
            }
            3 => {
                let i = rng.random_range(0..self.data.len());
                self.data[i].name.push_str("_x");
                format!("dataset '{}' renamed", self.data[i].name)
            }
            4 => self.reshape(rng),
            5 => self.poison_values(rng),
            6 => self.retype(rng),
            7 => {
                let i = rng.random_range(0..self.data.len());
                let d = &mut self.data[i];
                d.floats = d.floats.as_ref().map(|_| Vec::new());
                d.ints.clear();
                d.shape[0] = 0;
                format!("dataset '{}' emptied", d.name)
            }
            _ => {
                let mut extra = self.data[rng.random_range(0..self.data.len())].clone();
                extra.name = "unexpected".into();
                self.data.push(extra);
                "an extra dataset 'unexpected' added".into()
            }
        }
    }

    fn drop_attr(&mut self, rng: &mut ChaCha8Rng) -> String {
        if self.attrs.is_empty() {
            return "no attribute".into();
        }
        let i = rng.random_range(0..self.attrs.len());
        format!("attribute '{}' dropped", self.attrs.remove(i).0)
    }

    fn poison_attr(&mut self, rng: &mut ChaCha8Rng) -> String {
        if self.attrs.is_empty() {
            return "no attribute".into();
        }
        let i = rng.random_range(0..self.attrs.len());
        let v = [
            AttrValue::F64(f64::NAN),
            AttrValue::F64(f64::INFINITY),
            AttrValue::F64(-1.0),
            AttrValue::F64(0.0),
            AttrValue::F64(1e300),
            AttrValue::U64(u64::MAX),
            AttrValue::I64(-7),
            AttrValue::VarLenString("meanfield".into()),
            AttrValue::VarLenString("particle".into()),
            AttrValue::VarLenString("99".into()),
            AttrValue::U64(99),
        ]
        .choose(rng)
        .cloned()
        .unwrap_or(AttrValue::F64(f64::NAN));
        let what = format!("attribute '{}' set to {v:?}", self.attrs[i].0);
        self.attrs[i].1 = v;
        what
    }

    /// Rows dropped or added: counts that disagree between datasets, or with the attributes.
    fn reshape(&mut self, rng: &mut ChaCha8Rng) -> String {
        let i = rng.random_range(0..self.data.len());
        let d = &mut self.data[i];
        let row: usize = d.shape.iter().skip(1).product::<u64>().max(1) as usize;
        let len = d.floats.as_ref().map_or(d.ints.len(), Vec::len);
        if rng.random_bool(0.5) && len >= row && d.shape[0] > 0 {
            d.shape[0] -= 1;
            if let Some(f) = &mut d.floats {
                f.truncate(len - row);
            }
            d.ints.truncate(len.saturating_sub(row));
            format!("dataset '{}': last row dropped", d.name)
        } else {
            d.shape[0] += 1;
            if let Some(f) = &mut d.floats {
                f.extend(std::iter::repeat_n(0.5, row));
            } else {
                d.ints.extend(std::iter::repeat_n(1, row));
            }
            format!("dataset '{}': a row added", d.name)
        }
    }

    fn poison_values(&mut self, rng: &mut ChaCha8Rng) -> String {
        let i = rng.random_range(0..self.data.len());
        let d = &mut self.data[i];
        let v = *[
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            1e300,
            -1e300,
            0.0,
            -5.0,
        ]
        .choose(rng)
        .unwrap_or(&f64::NAN);
        let len = d.floats.as_ref().map_or(d.ints.len(), Vec::len);
        if len == 0 {
            return format!("dataset '{}' empty: unchanged", d.name);
        }
        let at = rng.random_range(0..len);
        match &mut d.floats {
            Some(f) => f[at] = v,
            None => d.ints[at] = if v.is_finite() { v as i64 } else { i64::MAX },
        }
        format!("dataset '{}': element {at} set to {v}", d.name)
    }

    /// Floats stored as integers (rounded) or integers as floats.
    fn retype(&mut self, rng: &mut ChaCha8Rng) -> String {
        let i = rng.random_range(0..self.data.len());
        let d = &mut self.data[i];
        match d.floats.take() {
            Some(f) => {
                d.ints = f.iter().map(|v| v.round() as i64).collect();
                format!("dataset '{}' stored as integers", d.name)
            }
            None => {
                d.floats = Some(d.ints.iter().map(|&v| v as f64 + 0.25).collect());
                d.ints.clear();
                format!("dataset '{}' stored as non-whole floats", d.name)
            }
        }
    }
}
