//! A CUDA compile check that needs neither a GPU nor a CUDA toolkit: a kernel set compiled
//! for a device (`sm_80`, device code only) by clang's CUDA front end and its NVPTX back end,
//! with a prelude that declares what NVRTC gives a source without includes (qualifiers,
//! `double2`, the atomics, the math functions the kernels call), and each kernel's local
//! memory (its stack, callees included) and static shared memory (at most
//! [`STATIC_SHARED_LIMIT`] per block, or it does not load) read off the PTX.
//!
//! Why: the kernels run on the host emulation in CI, compiled as C++, which accepts code that
//! no CUDA compiler does (a helper without `__device__`, a host-only call), and a kernel whose
//! arrays are indexed by values known only at run time keeps them in local memory. The driver
//! reserves a kernel's stack for every thread the device can hold (on an H100, 132 x 2 048
//! threads: 1 KB per thread is 0.28 GB), so a stack costs device memory as well as time. This
//! is clang's compiler, not NVRTC's: the device's own `ptxas` is the final word on stacks
//! (`scripts/device_run.sh ptxas`). Clang inlines and unrolls less than NVRTC, so it keeps
//! arrays in local memory that NVRTC may not (every stack ptxas reported on the H100, clang
//! finds too); a kernel that passes here has every index known once its loops are unrolled,
//! which neither compiler needs a stack for. What it cannot see: the math library's own local
//! memory (its functions stay calls here; CUDA's double `sin` and `cos` keep a small array for
//! their slow path).

use crate::error::GpuError;
use crate::host::first_that_runs;
use crate::kernel::KernelSet;
use std::collections::BTreeMap;

/// What a source without includes sees under NVRTC, declared for clang's CUDA mode (which,
/// with `-nocudainc`, has only its own built-in variables). A function a kernel calls that is
/// not here, nor in the source, is an error of the check: add it here only if CUDA has it.
const PRELUDE: &str = r#"
#define __global__ __attribute__((global))
#define __device__ __attribute__((device))
#define __host__ __attribute__((host))
#define __shared__ __attribute__((shared))
#define __constant__ __attribute__((constant))
#define __forceinline__ __inline__ __attribute__((always_inline))
#define __launch_bounds__(...) __attribute__((launch_bounds(__VA_ARGS__)))
#include <__clang_cuda_builtin_vars.h>
struct __attribute__((aligned(16))) double2 { double x, y; };
__device__ static inline double2 make_double2(double x, double y) {
    double2 r; r.x = x; r.y = y; return r;
}
__device__ static inline double atomicAdd(double* p, double v) {
    return __nvvm_atom_add_gen_d(p, v);
}
__device__ static inline int atomicAdd(int* p, int v) { return __nvvm_atom_add_gen_i(p, v); }
__device__ static inline unsigned atomicAdd(unsigned* p, unsigned v) {
    return (unsigned)__nvvm_atom_add_gen_i((int*)p, (int)v);
}
__device__ static inline int atomicCAS(int* p, int c, int v) {
    return __nvvm_atom_cas_gen_i(p, c, v);
}
#define MOTILE_M1(f) __device__ double f(double);
#define MOTILE_M2(f) __device__ double f(double, double);
MOTILE_M1(sqrt) MOTILE_M1(rsqrt) MOTILE_M1(cbrt) MOTILE_M1(exp) MOTILE_M1(expm1)
MOTILE_M1(log) MOTILE_M1(log1p) MOTILE_M1(erf) MOTILE_M1(erfc) MOTILE_M1(floor) MOTILE_M1(ceil)
MOTILE_M1(rint) MOTILE_M1(round) MOTILE_M1(trunc) MOTILE_M1(fabs) MOTILE_M1(sin) MOTILE_M1(cos)
MOTILE_M1(tan) MOTILE_M1(asin) MOTILE_M1(acos) MOTILE_M1(atan) MOTILE_M1(sinh) MOTILE_M1(cosh)
MOTILE_M1(tanh)
MOTILE_M2(pow) MOTILE_M2(fmin) MOTILE_M2(fmax) MOTILE_M2(fmod) MOTILE_M2(atan2)
MOTILE_M2(hypot) MOTILE_M2(copysign)
__device__ double fma(double, double, double);
__device__ void sincos(double, double*, double*);
__device__ int isfinite(double);
__device__ int isnan(double);
__device__ int isinf(double);
__device__ int min(int, int);
__device__ int max(int, int);
__device__ unsigned min(unsigned, unsigned);
__device__ unsigned max(unsigned, unsigned);
__device__ long long min(long long, long long);
__device__ long long max(long long, long long);
__device__ double min(double, double);
__device__ double max(double, double);
"#;

/// The compiler's flags (after `-x cuda`): device code only, for `sm_80` (supported from clang
/// 11; double `atomicAdd` needs `sm_60`), no CUDA headers or libdevice (the math functions
/// stay calls, which is all the check needs), optimised as a device compiler would.
const FLAGS: [&str; 9] = [
    "--cuda-device-only",
    "--cuda-gpu-arch=sm_80",
    "-nocudainc",
    "-nocudalib",
    "-std=c++17",
    "-O3",
    "-Wno-pass-failed",
    "-Wno-unknown-cuda-version",
    "-S",
];

/// A kernel set compiled for a device by [`compile_for_device`].
#[derive(Clone, Debug)]
pub struct DeviceCompile {
    /// The compiler (command and its version line).
    pub compiler: String,
    /// Each kernel's local memory per thread in bytes (its own and its deepest callee's),
    /// by name: every `__global__` function of the source.
    pub stacks: BTreeMap<String, u64>,
    /// Each kernel's static shared memory per block in bytes (the `__shared__` arrays it or
    /// its callees use), by name.
    pub shared: BTreeMap<String, u64>,
}

/// The static shared memory a block may declare (48 KB on every device since `sm_20`; more
/// needs dynamic shared memory and an opt-in): a kernel over it does not load.
pub const STATIC_SHARED_LIMIT: u64 = 48 * 1024;

impl DeviceCompile {
    /// The kernels that keep a stack, with its bytes, other than those in `allowed`.
    pub fn with_stack(&self, allowed: &[&str]) -> Vec<(String, u64)> {
        self.stacks
            .iter()
            .filter(|(k, s)| **s > 0 && !allowed.contains(&k.as_str()))
            .map(|(k, s)| (k.clone(), *s))
            .collect()
    }
}

/// A clang that compiles CUDA device code: `MOTILE_CUDA_CLANG` if set, else the first of
/// `clang`, `clang-19` ... `clang-14` that runs; `Err` says why none does.
pub fn device_compiler() -> Result<String, String> {
    let named = std::env::var("MOTILE_CUDA_CLANG").ok();
    let candidates: Vec<String> = match &named {
        Some(c) => vec![c.clone()],
        None => std::iter::once("clang".to_string())
            .chain((14..=19).rev().map(|v| format!("clang-{v}")))
            .collect(),
    };
    first_that_runs(&candidates)
        .map(|c| c.command)
        .ok_or_else(|| {
            format!(
                "the CUDA compile check needs clang (CUDA device code) and none of {} runs",
                candidates.join(", ")
            )
        })
}

/// `set` compiled for a device by `clang` (see the module's text), or the compiler's errors.
pub fn compile_for_device(set: &KernelSet, clang: &str) -> Result<DeviceCompile, GpuError> {
    let dir = tempfile::tempdir().map_err(|e| GpuError::Compile(format!("a temp dir: {e}")))?;
    let src = dir.path().join("kernels.cu");
    let ptx = dir.path().join("kernels.ptx");
    let flags: Vec<&str> = ["-x", "cuda"].into_iter().chain(FLAGS).collect();
    let text = format!("{PRELUDE}\n{}", set.source);
    crate::host::compile_file(clang, &flags, &text, &src, &ptx)?;
    let text = std::fs::read_to_string(&ptx)
        .map_err(|e| GpuError::Compile(format!("reading {}: {e}", ptx.display())))?;
    let version = first_that_runs(&[clang.to_string()])
        .and_then(|c| c.version.lines().next().map(str::to_string))
        .unwrap_or_default();
    Ok(DeviceCompile {
        compiler: format!("{clang}: {version}"),
        stacks: kernel_stacks(&text),
        shared: kernel_shared(&text),
    })
}

/// Why [`check_set`] did not pass.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// No clang runs here.
    #[error("{0}")]
    NoCompiler(String),
    /// The set did not compile, or a kernel keeps a stack, or one named as keeping one keeps
    /// none, or a declaration names no kernel.
    #[error("{0}")]
    Failed(String),
}

/// The kernel sets' check: `set` compiles for a device, every kernel it declares is a kernel of
/// the compiled module, every name in `allowed` too, those keep a stack (the list is not
/// stale) and no other kernel does.
pub fn check_set(set: &KernelSet, allowed: &[&str]) -> Result<DeviceCompile, CheckError> {
    let clang = device_compiler().map_err(CheckError::NoCompiler)?;
    let c = compile_for_device(set, &clang).map_err(|e| CheckError::Failed(e.to_string()))?;
    let missing: Vec<&str> = set
        .names()
        .into_iter()
        .chain(allowed.iter().copied())
        .filter(|k| !c.stacks.contains_key(*k))
        .collect();
    if !missing.is_empty() {
        return Err(CheckError::Failed(format!(
            "{}: no kernel {missing:?} in the compiled module",
            c.compiler
        )));
    }
    let over: Vec<_> = c
        .shared
        .iter()
        .filter(|(_, b)| **b > STATIC_SHARED_LIMIT)
        .collect();
    if !over.is_empty() {
        return Err(CheckError::Failed(format!(
            "{}: kernels over {STATIC_SHARED_LIMIT} bytes of static shared memory per block \
             {over:?}: they would not load on a device",
            c.compiler
        )));
    }
    let stale: Vec<&&str> = allowed.iter().filter(|k| c.stacks[**k] == 0).collect();
    if !stale.is_empty() {
        return Err(CheckError::Failed(format!(
            "{}: {stale:?} named as keeping a stack keep none: take them off the list",
            c.compiler
        )));
    }
    let with_stack = c.with_stack(allowed);
    if !with_stack.is_empty() {
        return Err(CheckError::Failed(format!(
            "{}: kernels with a stack (bytes per thread) {with_stack:?}: an array indexed by a \
             value known only at run time, or a value passed by address to a call that was \
             not inlined",
            c.compiler
        )));
    }
    Ok(c)
}

/// [`check_set`] as the kernel sets' tests run it: a line to show where it passed or where no
/// clang runs (not run, and why), an error where it failed, and also where no clang runs but
/// `MOTILE_REQUIRE_CUDA_CLANG` is set (as the README's test command sets it).
pub fn check_set_in_test(set: &KernelSet, allowed: &[&str]) -> Result<String, String> {
    match check_set(set, allowed) {
        Ok(c) => Ok(format!(
            "{}: {} kernels compiled for sm_80, a stack only in {allowed:?}, static shared \
             memory at most {} bytes per block",
            c.compiler,
            c.stacks.len(),
            c.shared.values().max().unwrap_or(&0)
        )),
        Err(CheckError::NoCompiler(why)) if std::env::var("MOTILE_REQUIRE_CUDA_CLANG").is_err() => {
            Ok(format!("not run: {why}"))
        }
        Err(e) => Err(e.to_string()),
    }
}

/// One function of a PTX module: whether it is a kernel, the local memory it uses itself, and
/// the functions it calls.
#[derive(Debug, Default)]
struct PtxFunction {
    entry: bool,
    local: u64,
    calls: Vec<String>,
    /// Every identifier its body names (for the shared arrays it uses).
    names: std::collections::BTreeSet<String>,
}

/// Each kernel (`.entry`) of `ptx` with its stack: its own local memory plus the deepest chain
/// of its callees'. A function's local memory is its `__local_depot` arrays where its body
/// uses them (an unused depot, which some back ends leave behind, costs nothing once
/// assembled).
fn kernel_stacks(ptx: &str) -> BTreeMap<String, u64> {
    let funcs = ptx_functions(ptx);
    let mut out = BTreeMap::new();
    for (name, f) in &funcs {
        if f.entry {
            out.insert(name.clone(), stack_of(name, &funcs, &mut Vec::new()));
        }
    }
    out
}

/// Each kernel of `ptx` with its static shared memory: the module's `.shared` arrays named in
/// its body or in a callee's (clang declares an array that one function uses in that function's
/// body, marked "demoted variable", and others at module scope).
fn kernel_shared(ptx: &str) -> BTreeMap<String, u64> {
    let arrays: Vec<(String, u64)> = ptx.lines().filter_map(shared_array).collect();
    let funcs = ptx_functions(ptx);
    let mut out = BTreeMap::new();
    for (name, f) in &funcs {
        if !f.entry {
            continue;
        }
        let mut reached = vec![name.clone()];
        let mut k = 0;
        while k < reached.len() {
            if let Some(g) = funcs.get(&reached[k]) {
                for c in &g.calls {
                    if !reached.contains(c) {
                        reached.push(c.clone());
                    }
                }
            }
            k += 1;
        }
        let bytes = arrays
            .iter()
            .filter(|(a, _)| {
                reached
                    .iter()
                    .any(|r| funcs.get(r).is_some_and(|g| g.names.contains(a)))
            })
            .map(|(_, b)| b)
            .sum();
        out.insert(name.clone(), bytes);
    }
    out
}

/// `(name, bytes)` of `.shared .align A .b8 NAME[SIZE];`, also after `.visible` (a file-scope
/// array) or `.weak` (one in an inline function that several kernels call).
fn shared_array(line: &str) -> Option<(String, u64)> {
    let t = without_linkage(line).strip_prefix(".shared")?;
    let decl = t.split_whitespace().last()?;
    let open = decl.find('[')?;
    let close = decl.find(']')?;
    Some((
        decl[..open].to_string(),
        decl[open + 1..close].parse().ok()?,
    ))
}

/// Local memory of `name` and its deepest callee chain (a recursive call counted once).
fn stack_of(name: &str, funcs: &BTreeMap<String, PtxFunction>, path: &mut Vec<String>) -> u64 {
    let Some(f) = funcs.get(name) else { return 0 };
    path.push(name.to_string());
    let callees: Vec<&String> = f.calls.iter().filter(|c| !path.contains(c)).collect();
    let deepest = callees
        .into_iter()
        .map(|c| stack_of(c, funcs, path))
        .max()
        .unwrap_or(0);
    path.pop();
    f.local + deepest
}

/// The functions defined in `ptx` (declarations without a body are skipped; a body is what
/// lies between its head and the next head).
fn ptx_functions(ptx: &str) -> BTreeMap<String, PtxFunction> {
    let lines: Vec<&str> = ptx.lines().collect();
    let heads: Vec<(usize, bool, String)> = lines
        .iter()
        .enumerate()
        .filter_map(|(i, l)| function_head(l).map(|(entry, name)| (i, entry, name)))
        .collect();
    let mut funcs = BTreeMap::new();
    for (k, (start, entry, name)) in heads.iter().enumerate() {
        let end = heads.get(k + 1).map_or(lines.len(), |h| h.0);
        let body = &lines[start + 1..end];
        if !body.iter().any(|l| l.trim() == "{") {
            continue;
        }
        let depot: u64 = body.iter().filter_map(|l| depot_bytes(l)).sum();
        let used = body.iter().any(|l| {
            let t = l.trim();
            t.starts_with("ld.local")
                || t.starts_with("st.local")
                || (t.contains("%SP") && !t.starts_with(".reg") && !is_depot_setup(t))
        });
        let calls = body
            .iter()
            .enumerate()
            .filter(|(_, l)| l.trim_start().starts_with("call"))
            .filter_map(|(i, _)| called_name(&body[i..]))
            .collect();
        let names = body
            .iter()
            .flat_map(|l| l.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '$')))
            .filter(|w| !w.is_empty())
            .map(str::to_string)
            .collect();
        funcs.insert(
            name.clone(),
            PtxFunction {
                entry: *entry,
                local: if used { depot } else { 0 },
                calls,
                names,
            },
        );
    }
    funcs
}

/// `(is a kernel, name)` where `line` starts a function: `.visible .entry name(`, `.func name(`,
/// `.weak .func (.param ...) name(`.
fn function_head(line: &str) -> Option<(bool, String)> {
    let t = without_linkage(line);
    let (entry, rest) = if let Some(r) = t.strip_prefix(".entry") {
        (true, r)
    } else if let Some(r) = t.strip_prefix(".func") {
        (false, r)
    } else {
        return None;
    };
    let mut rest = rest.trim_start();
    if rest.starts_with('(') {
        // the return value's parameter list
        rest = rest[rest.find(')')? + 1..].trim_start();
    }
    let name: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '$')
        .collect();
    (!name.is_empty()).then_some((entry, name))
}

/// `line` without its leading space and linkage (`.visible`, `.weak`, `.extern`).
fn without_linkage(line: &str) -> &str {
    let mut t = line.trim();
    for prefix in [".visible", ".weak", ".extern"] {
        t = t.strip_prefix(prefix).map_or(t, str::trim_start);
    }
    t
}

/// The bytes of `.local .align A .b8 __local_depotN[SIZE];`.
fn depot_bytes(line: &str) -> Option<u64> {
    let t = line.trim();
    if !t.starts_with(".local") {
        return None;
    }
    let at = t.find("__local_depot")?;
    let open = at + t[at..].find('[')?;
    let close = open + t[open..].find(']')?;
    t[open + 1..close].parse().ok()
}

/// The two instructions that set up a depot's pointers (`mov.u64 %SPL, __local_depotN;`,
/// `cvta.local.u64 %SP, %SPL;`), which every function with a depot has, used or not.
fn is_depot_setup(t: &str) -> bool {
    let t = t.replace(char::is_whitespace, "");
    t.starts_with("mov.u64%SPL,__local_depot") || t == "cvta.local.u64%SP,%SPL;"
}

/// The function a `call` names: the first identifier after `call...` and an optional
/// `(return values),`, on the call's line or the next ones.
fn called_name(from: &[&str]) -> Option<String> {
    let mut text = String::new();
    for l in from.iter().take(4) {
        text.push_str(l.trim());
        text.push(' ');
    }
    let rest = text.strip_prefix("call")?;
    let mut rest = rest[rest.find(char::is_whitespace)?..].trim_start();
    if rest.starts_with('(') {
        rest = rest[rest.find(')')? + 1..].trim_start();
        rest = rest.strip_prefix(',')?.trim_start();
    }
    let name: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '$')
        .collect();
    (!name.is_empty()).then_some(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A function as clang writes it: `head`, a depot of `depot` bytes with its set-up (none
    /// for 0), then `body`.
    fn function(head: &str, depot: u64, body: &[&str]) -> String {
        let mut f = format!("{head}\n\t.param .u64 p0\n)\n{{\n");
        if depot > 0 {
            f += &format!("\t.local .align 8 .b8 \t__local_depot{depot}[{depot}];\n");
            f += "\t.reg .b64 \t%SP;\n\t.reg .b64 \t%SPL;\n";
            f += &format!("\tmov.u64 \t%SPL, __local_depot{depot};\n");
            f += "\tcvta.local.u64 \t%SP, %SPL;\n";
        }
        for l in body {
            f += &format!("\t{l}\n");
        }
        f + "\tret;\n}\n"
    }

    /// A module: a declaration, a device function with a used depot called by one kernel, a
    /// kernel with an unused depot, a kernel without.
    fn module() -> String {
        let helper = ".weak .func  (.param .b64 func_retval0) _Z4helpPd(";
        [
            format!("{helper}\n\t.param .b64 p0\n)\n;\n"),
            function(
                ".visible .entry uses_helper(",
                16,
                &[
                    "add.u64 \t%rd1, %SP, 0;",
                    "{ // callseq 0, 0",
                    "call.uni (retval0), ",
                    "_Z4helpPd, ",
                    "(",
                    "param0",
                    ");",
                    "} // callseq 0",
                ],
            ),
            function(helper, 96, &["st.local.f64 \t[%rd2], %fd1;"]),
            function(".visible .entry unused_depot(", 8, &[]),
            function(".visible .entry plain(", 0, &[]),
        ]
        .concat()
    }

    #[test]
    fn stacks_count_the_used_depots_of_a_kernel_and_its_callees() {
        let s = kernel_stacks(&module());
        assert_eq!(
            s.into_iter().collect::<Vec<_>>(),
            vec![
                ("plain".to_string(), 0),
                ("unused_depot".to_string(), 0),
                ("uses_helper".to_string(), 16 + 96),
            ]
        );
    }

    /// What the host emulation's C++ compiler takes and a CUDA compiler does not: a kernel
    /// calling a function not declared `__device__`; and a kernel that indexes a local array
    /// with a value known only at run time keeps a stack.
    #[test]
    fn a_host_function_in_a_kernel_fails_and_an_indexed_array_keeps_a_stack() {
        let clang = match device_compiler() {
            Ok(c) => c,
            Err(why) if std::env::var("MOTILE_REQUIRE_CUDA_CLANG").is_err() => {
                return eprintln!("not run: {why}");
            }
            Err(why) => panic!("{why}"),
        };
        let set = |source| KernelSet {
            source,
            kernels: &[],
        };
        let host_call = "double twice(double x) { return 2.0 * x; }\n\
            extern \"C\" __global__ void k(double* v) { v[threadIdx.x] = twice(v[0]); }";
        let err = compile_for_device(&set(host_call), &clang).unwrap_err();
        assert!(err.to_string().contains("twice"), "{err}");
        let indexed = "extern \"C\" __global__ void k(double* v, int i) {\n\
            double a[8];\n\
            for (int q = 0; q < 8; ++q) a[q] = v[q];\n\
            v[0] = a[i & 7];\n\
            }\n\
            extern \"C\" __global__ void plain(double* v) { v[0] += 1.0; }";
        let c = compile_for_device(&set(indexed), &clang).unwrap();
        assert_eq!(c.with_stack(&[]), vec![("k".to_string(), 64)], "{c:?}");
        assert_eq!(c.stacks.get("plain"), Some(&0));
        let big = "extern \"C\" __global__ void k(double* v) {\n\
            __shared__ double s[6200];\n\
            s[threadIdx.x] = v[threadIdx.x];\n\
            v[threadIdx.x] = s[255 - threadIdx.x];\n\
            }";
        let c = compile_for_device(&set(big), &clang).unwrap();
        assert_eq!(c.shared.get("k"), Some(&(6200 * 8)), "{c:?}");
        assert!(
            check_set(&set(big), &[]).is_err_and(|e| e.to_string().contains("shared memory")),
            "a kernel over 48 KB of static shared memory passes"
        );
    }

    /// A kernel's shared arrays: its own and its callees', each once.
    #[test]
    fn shared_memory_counts_the_arrays_a_kernel_and_its_callees_name() {
        let helper = ".func _Z4helpv(";
        let ptx = [
            ".weak .shared .align 4 .b8 _ZZ4helpvE1t[256];\n".to_string(),
            ".visible .shared .align 8 .b8 file_scope[64];\n".to_string(),
            function(
                ".visible .entry a(",
                0,
                &[
                    "// demoted variable",
                    ".shared .align 8 .b8 _ZZ1aE2st[1024];",
                    "mov.u64 \t%rd1, _ZZ1aE2st;",
                    "call.uni ",
                    "_Z4helpv, ",
                    "(",
                    ");",
                ],
            ),
            function(helper, 0, &["mov.u64 \t%rd2, _ZZ4helpvE1t;"]),
            function(".visible .entry b(", 0, &["mov.u64 \t%rd3, _ZZ4helpvE1t;"]),
            function(".visible .entry c(", 0, &["mov.u64 \t%rd4, file_scope;"]),
        ]
        .concat();
        let s = kernel_shared(&ptx);
        assert_eq!(
            s.into_iter().collect::<Vec<_>>(),
            vec![
                ("a".to_string(), 1024 + 256),
                ("b".to_string(), 256),
                ("c".to_string(), 64)
            ]
        );
    }

    #[test]
    fn heads_and_calls_are_read_in_their_forms() {
        assert_eq!(
            function_head(".visible .entry k("),
            Some((true, "k".to_string()))
        );
        assert_eq!(
            function_head(".weak .func  (.param .b64 func_retval0) _Z1fv("),
            Some((false, "_Z1fv".to_string()))
        );
        assert_eq!(
            function_head(".func _Z1gv()"),
            Some((false, "_Z1gv".to_string()))
        );
        assert_eq!(function_head("\tret;"), None);
        assert_eq!(
            called_name(&["\tcall.uni ", "\t_Z1gv, ", "\t("]).as_deref(),
            Some("_Z1gv")
        );
        assert_eq!(
            called_name(&["\tcall.uni (retval0), ", "\t_Z1fv, "]).as_deref(),
            Some("_Z1fv")
        );
        assert_eq!(
            depot_bytes("\t.local .align 8 .b8 \t__local_depot7[624];"),
            Some(624)
        );
    }
}
