//! Typed kernel launches: each kernel's parameters declared once, as a struct with named fields
//! ([`crate::kernels!`]), beside the kernel's CUDA source, and checked against that source's
//! signature when a device opens it. A launch with a missing, extra or mistyped argument does
//! not compile, and two arguments of one type cannot be swapped unnoticed: they are named.

use crate::buffer::Buffer;

/// Threads per block of every launch.
pub const THREADS: u32 = 256;

/// One argument of a launch, as the backends pass it (built by [`KernelArg::arg`]).
#[doc(hidden)]
#[derive(Debug)]
pub enum Arg<'a> {
    /// `const double*` (or `const double2*`).
    InF64(&'a Buffer<f64>),
    /// `double*` (or `double2*`).
    OutF64(&'a mut Buffer<f64>),
    /// `const int*`.
    InI32(&'a Buffer<i32>),
    /// `int*`.
    OutI32(&'a mut Buffer<i32>),
    /// `const unsigned int*`.
    InU32(&'a Buffer<u32>),
    /// `unsigned int*`.
    OutU32(&'a mut Buffer<u32>),
    /// `int`.
    Int(i32),
    /// `long long`.
    Long(i64),
    /// `double`.
    Real(f64),
}

impl Arg<'_> {
    /// The code of the C parameter type this argument fits ([`c_type_code`]).
    pub(crate) fn code(&self) -> char {
        match self {
            Arg::InF64(_) => 'i',
            Arg::OutF64(_) => 'o',
            Arg::InI32(_) => 'j',
            Arg::OutI32(_) => 'p',
            Arg::InU32(_) => 'u',
            Arg::OutU32(_) => 'v',
            Arg::Int(_) => 'n',
            Arg::Long(_) => 'l',
            Arg::Real(_) => 'r',
        }
    }
}

/// The code of a C parameter type: `i` `const double*` or `const double2*`, `o` `double*` or
/// `double2*`, `j` `const int*`, `p` `int*`, `u` `const unsigned int*`, `v` `unsigned int*`,
/// `n` `int`, `l` `long long`, `r` `double`; `None` for any other type.
pub fn c_type_code(c_type: &str) -> Option<char> {
    let t: String = c_type.split_whitespace().collect::<Vec<_>>().join(" ");
    let t = t.replace(" *", "*");
    Some(match t.as_str() {
        "const double*" | "const double2*" => 'i',
        "double*" | "double2*" => 'o',
        "const int*" => 'j',
        "int*" => 'p',
        "const unsigned int*" | "const unsigned*" => 'u',
        "unsigned int*" | "unsigned*" => 'v',
        "int" => 'n',
        "long long" => 'l',
        "double" => 'r',
        _ => return None,
    })
}

/// A Rust value a kernel parameter takes: `&Buffer<T>` for a `const T*`, `&mut Buffer<T>` for a
/// `T*`, `i32` for an `int`, `i64` for a `long long`, `f64` for a `double`.
pub trait KernelArg {
    /// The code of the C parameter type it fits ([`c_type_code`]).
    const CODE: char;
    /// The argument as the backends pass it.
    #[doc(hidden)]
    fn arg(&mut self) -> Arg<'_>;
}

macro_rules! buffer_args {
    ($t:ty, $in:ident, $out:ident, $ci:literal, $co:literal) => {
        impl KernelArg for &Buffer<$t> {
            const CODE: char = $ci;
            fn arg(&mut self) -> Arg<'_> {
                Arg::$in(self)
            }
        }
        impl KernelArg for &mut Buffer<$t> {
            const CODE: char = $co;
            fn arg(&mut self) -> Arg<'_> {
                Arg::$out(self)
            }
        }
    };
}
buffer_args!(f64, InF64, OutF64, 'i', 'o');
buffer_args!(i32, InI32, OutI32, 'j', 'p');
buffer_args!(u32, InU32, OutU32, 'u', 'v');

impl KernelArg for i32 {
    const CODE: char = 'n';
    fn arg(&mut self) -> Arg<'_> {
        Arg::Int(*self)
    }
}

impl KernelArg for i64 {
    const CODE: char = 'l';
    fn arg(&mut self) -> Arg<'_> {
        Arg::Long(*self)
    }
}

impl KernelArg for f64 {
    const CODE: char = 'r';
    fn arg(&mut self) -> Arg<'_> {
        Arg::Real(*self)
    }
}

/// A kernel's arguments: a struct declared by [`crate::kernels!`].
pub trait Kernel {
    /// The kernel's name in its source.
    const NAME: &'static str;
    /// Each parameter's name and type code, in order.
    const PARAMS: &'static [(&'static str, char)];
    /// The arguments, in the parameters' order.
    #[doc(hidden)]
    fn args(&mut self) -> Vec<Arg<'_>>;
}

/// A kernel source and the declarations of its kernels ([`crate::kernels!`] makes one).
#[derive(Clone, Copy, Debug)]
pub struct KernelSet {
    /// The CUDA C source.
    pub source: &'static str,
    /// Each kernel's name and parameters (name, type code).
    pub kernels: &'static [(&'static str, &'static [(&'static str, char)])],
}

impl KernelSet {
    /// The kernels' names.
    pub fn names(&self) -> Vec<&'static str> {
        self.kernels.iter().map(|(n, _)| *n).collect()
    }

    /// Check every declaration against the source: each kernel is an `extern "C" __global__`
    /// function whose parameters have the declared names, order and types. The error names
    /// the kernel and the first parameter that differs.
    pub fn check(&self) -> Result<(), String> {
        for (name, params) in self.kernels {
            let found = signature(self.source, name)?;
            if found.len() != params.len() {
                return Err(format!(
                    "kernel {name}: the source has {} parameters, the declaration {}",
                    found.len(),
                    params.len()
                ));
            }
            for (k, ((sn, sc), (dn, dc))) in found.iter().zip(params.iter()).enumerate() {
                if sn != dn || sc != dc {
                    return Err(format!(
                        "kernel {name}, parameter {k}: the source has `{sn}` of type code {sc}, \
                         the declaration `{dn}` of type code {dc}"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The parameters (name, type code) of kernel `name` in `source`: the `__global__` function
/// whose head (up to its body's `{`) has `name(` in it (attributes such as
/// `__launch_bounds__(..)` may stand before the name).
fn signature(source: &str, name: &str) -> Result<Vec<(String, char)>, String> {
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let at = source
        .match_indices("__global__")
        .find_map(|(i, _)| {
            let head = &source[i..i + source[i..].find('{')?];
            head.match_indices(&format!("{name}("))
                .find(|&(k, _)| !head[..k].ends_with(is_ident))
                .map(|(k, m)| i + k + m.len())
        })
        .ok_or_else(|| format!("kernel {name}: no `__global__ void {name}(` in the source"))?;
    let close = source[at..]
        .find(')')
        .ok_or_else(|| format!("kernel {name}: unclosed parameter list"))?;
    source[at..at + close]
        .split(',')
        .map(|p| {
            let p = p.trim();
            let split = p
                .rfind(|c: char| !is_ident(c))
                .ok_or_else(|| format!("kernel {name}: cannot read parameter `{p}`"))?;
            let (ty, pname) = (&p[..=split], &p[split + 1..]);
            let code = c_type_code(ty)
                .ok_or_else(|| format!("kernel {name}: parameter `{p}` of an unsupported type"))?;
            Ok((pname.to_string(), code))
        })
        .collect()
}

/// Declares kernels: for each, a struct of its arguments with named fields (in the kernel's
/// parameter order) that implements [`Kernel`], and one [`KernelSet`] of them all with their
/// source. Field types: `&'a Buffer<T>` for `const T*`, `&'a mut Buffer<T>` for `T*`, `i32`
/// for `int`, `i64` for `long long`, `f64` for `double`.
///
/// ```
/// use motile_gpu::Buffer;
/// motile_gpu::kernels! {
///     /// The kernels of this example.
///     const KERNELS = "extern \"C\" __global__ void axpy(const double* x, double* y, int n, double a) {}";
///     /// `y += a x`.
///     struct Axpy = "axpy" { x: &'a Buffer<f64>, y: &'a mut Buffer<f64>, n: i32, a: f64 }
/// }
/// KERNELS.check().unwrap();
/// ```
///
/// An argument of the wrong type does not compile (here an `f64` count where the kernel takes
/// an `int`):
///
/// ```compile_fail,E0308
/// # use motile_gpu::Buffer;
/// # motile_gpu::kernels! {
/// #     const KERNELS = "";
/// #     struct Axpy = "axpy" { x: &'a Buffer<f64>, y: &'a mut Buffer<f64>, n: i32, a: f64 }
/// # }
/// fn launch<'a>(x: &'a Buffer<f64>, y: &'a mut Buffer<f64>) -> Axpy<'a> {
///     Axpy { x, y, n: 2.5, a: 1.0 }
/// }
/// ```
///
/// nor does an integer buffer where the kernel reads doubles (two buffers swapped):
///
/// ```compile_fail,E0308
/// # use motile_gpu::Buffer;
/// # motile_gpu::kernels! {
/// #     const KERNELS = "";
/// #     struct Gather = "gather" { start: &'a Buffer<i32>, x: &'a Buffer<f64>, out: &'a mut Buffer<f64> }
/// # }
/// fn launch<'a>(start: &'a Buffer<i32>, x: &'a Buffer<f64>, out: &'a mut Buffer<f64>) -> Gather<'a> {
///     Gather { start: x, x: start, out }
/// }
/// ```
///
/// and a declaration whose names or types differ from the source is refused by
/// [`KernelSet::check`] (and by [`crate::Device::open`]).
#[macro_export]
macro_rules! kernels {
    (
        $(#[$smeta:meta])*
        $svis:vis const $set:ident = $source:expr;
        $(
            $(#[$meta:meta])*
            $vis:vis struct $name:ident = $cname:literal {
                $( $(#[$fmeta:meta])* $field:ident : $ty:ty ),* $(,)?
            }
        )*
    ) => {
        $(
            $(#[$meta])*
            #[derive(Debug)]
            $vis struct $name<'a> {
                $( $(#[$fmeta])* pub $field: $ty, )*
            }

            impl<'a> $crate::Kernel for $name<'a> {
                const NAME: &'static str = $cname;
                const PARAMS: &'static [(&'static str, char)] =
                    &[$( (stringify!($field), <$ty as $crate::KernelArg>::CODE) ),*];
                fn args(&mut self) -> Vec<$crate::Arg<'_>> {
                    vec![$( $crate::KernelArg::arg(&mut self.$field) ),*]
                }
            }
        )*

        $(#[$smeta])*
        $svis const $set: $crate::KernelSet = $crate::KernelSet {
            source: $source,
            kernels: &[$( ($cname, <$name<'static> as $crate::Kernel>::PARAMS) ),*],
        };
    };
}
