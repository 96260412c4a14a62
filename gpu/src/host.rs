//! The host emulation: kernels compiled by the system's C++ compiler with a prelude that
//! defines CUDA's built-ins, loaded as a shared library, every thread run in turn.
#![allow(unsafe_code)]

use crate::buffer::Data;
use crate::error::GpuError;
use crate::kernel::{Arg, THREADS};
use std::collections::HashMap;
use std::ffi::{CStr, c_char, c_void};
use std::process::Command;

/// What the kernels see of CUDA: thread indices (thread-local), qualifiers as no-ops, atomics
/// (`atomicAdd` on double, int and unsigned, `atomicCAS` on int) under one lock, and
/// per kernel an entry point that runs every thread of every block and one that describes its
/// parameter types (the codes of `kernel::c_type_code`). A kernel that calls `__syncthreads`
/// runs each block's threads as concurrent OS threads with a barrier (its `__shared__` arrays
/// static: one block at a time); the others run their threads in turn. Blocks run in turn, or
/// shuffled at every launch (`Device::shuffle_blocks`), to expose races between blocks.
const PRELUDE: &str = r#"
#include <cmath>
#include <math.h>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <utility>
#include <thread>
#include <mutex>
#include <condition_variable>
#include <vector>
struct motile_dim3 { unsigned x, y, z; };
struct double2 { double x, y; };
static inline double2 make_double2(double x, double y) { return double2{x, y}; }
static thread_local motile_dim3 threadIdx, blockIdx;
static motile_dim3 blockDim, gridDim;
#define __global__
#define __device__
#define __host__
#define __constant__ const
#define __forceinline__ inline
#define __launch_bounds__(...)
// Shared memory: one block runs at a time, so a static array is the block's.
#define __shared__ static
// Atomics: one lock for all of them (threaded launches run a block's threads concurrently).
static std::mutex motile_atomic_lock;
template <typename T> static inline T motile_atomic_add(T* p, T v) {
    std::lock_guard<std::mutex> g(motile_atomic_lock);
    T old = *p;
    *p = old + v;
    return old;
}
static inline double atomicAdd(double* p, double v) { return motile_atomic_add(p, v); }
static inline int atomicAdd(int* p, int v) { return motile_atomic_add(p, v); }
static inline unsigned atomicAdd(unsigned* p, unsigned v) { return motile_atomic_add(p, v); }
static inline int atomicCAS(int* p, int compare, int v) {
    std::lock_guard<std::mutex> g(motile_atomic_lock);
    int old = *p;
    if (old == compare) *p = v;
    return old;
}
// The barrier of the block's threads (threaded launches only).
struct motile_barrier {
    std::mutex m;
    std::condition_variable cv;
    unsigned count = 0, waiting = 0, generation = 0;
    void wait() {
        std::unique_lock<std::mutex> lock(m);
        unsigned g = generation;
        if (++waiting == count) {
            waiting = 0;
            ++generation;
            cv.notify_all();
        } else {
            cv.wait(lock, [&] { return generation != g; });
        }
    }
};
static motile_barrier motile_block_barrier;
static thread_local bool motile_in_threaded_launch = false;
static inline void motile_syncthreads() {
    if (!motile_in_threaded_launch) {
        std::fprintf(stderr, "host emulation: __syncthreads in a kernel run thread by thread "
                             "(declare its __shared__ memory in the kernel's own body)\n");
        std::abort();
    }
    motile_block_barrier.wait();
}
#define __syncthreads() motile_syncthreads()
template <typename T> struct motile_code;
template <> struct motile_code<const double*> { static constexpr char c = 'i'; };
template <> struct motile_code<double*> { static constexpr char c = 'o'; };
template <> struct motile_code<const double2*> { static constexpr char c = 'i'; };
template <> struct motile_code<double2*> { static constexpr char c = 'o'; };
template <> struct motile_code<const int*> { static constexpr char c = 'j'; };
template <> struct motile_code<int*> { static constexpr char c = 'p'; };
template <> struct motile_code<const unsigned*> { static constexpr char c = 'u'; };
template <> struct motile_code<unsigned*> { static constexpr char c = 'v'; };
template <> struct motile_code<int> { static constexpr char c = 'n'; };
template <> struct motile_code<long long> { static constexpr char c = 'l'; };
template <> struct motile_code<double> { static constexpr char c = 'r'; };
template <typename... A> static const char* motile_signature(void (*)(A...)) {
    static const char s[] = {motile_code<A>::c..., '\0'};
    return s;
}
template <typename... A, std::size_t... I>
static void motile_call(void (*f)(A...), void** a, std::index_sequence<I...>) {
    f(*static_cast<A*>(a[I])...);
}
// The order blocks run in: in turn, or (motile_set_shuffle with a nonzero seed) a new random
// permutation at every launch, so that a kernel whose result depends on the order of its
// blocks (a race between blocks) gives different results from launch to launch.
static unsigned long long motile_shuffle = 0, motile_launches = 0;
extern "C" void motile_set_shuffle(unsigned long long seed) { motile_shuffle = seed; }
static std::vector<unsigned> motile_block_order(unsigned grid) {
    std::vector<unsigned> order(grid);
    for (unsigned b = 0; b < grid; ++b) order[b] = b;
    if (motile_shuffle != 0) {
        unsigned long long x = motile_shuffle + 0x9E3779B97F4A7C15ull * ++motile_launches;
        for (unsigned b = grid; b > 1; --b) {
            x ^= x >> 30; x *= 0xBF58476D1CE4E5B9ull; x ^= x >> 27; x *= 0x94D049BB133111EBull;
            x ^= x >> 31;
            std::swap(order[b - 1], order[x % b]);
        }
    }
    return order;
}
// Every thread of every block. Kernels without __syncthreads run their threads one after
// another on the calling thread; kernels with it (threaded) run each thread of a block as an
// OS thread, concurrently (the barrier and the atomics synchronise them, anything else races
// as on a GPU), the blocks one after another, a barrier between blocks.
template <bool Threaded, typename... A>
static void motile_launch(void (*f)(A...), unsigned grid, unsigned block, void** a) {
    gridDim = {grid, 1, 1};
    blockDim = {block, 1, 1};
    std::vector<unsigned> order = motile_block_order(grid);
    if (Threaded) {
        motile_block_barrier.count = block;
        std::vector<std::thread> threads;
        for (unsigned t = 0; t < block; ++t) {
            threads.emplace_back([=, &order] {
                motile_in_threaded_launch = true;
                for (unsigned b : order) {
                    blockIdx = {b, 0, 0};
                    threadIdx = {t, 0, 0};
                    motile_call(f, a, std::index_sequence_for<A...>{});
                    motile_block_barrier.wait();
                }
            });
        }
        for (auto& th : threads) th.join();
    } else {
        for (unsigned b : order) {
            for (unsigned t = 0; t < block; ++t) {
                blockIdx = {b, 0, 0};
                threadIdx = {t, 0, 0};
                motile_call(f, a, std::index_sequence_for<A...>{});
            }
        }
    }
}
#define MOTILE_ENTRY(name, threaded) \
    extern "C" void motile_run_##name(unsigned g, unsigned b, void** a) { motile_launch<threaded>(name, g, b, a); } \
    extern "C" const char* motile_sig_##name() { return motile_signature(name); }
"#;

// Pointers travel in 8-byte slots.
const _: () = assert!(std::mem::size_of::<usize>() == 8);

type Run = unsafe extern "C" fn(u32, u32, *mut *mut c_void);
type Sig = unsafe extern "C" fn() -> *const c_char;

/// The body of kernel `name` in `source`: the braces after its `__global__ ... name(`, matched
/// (empty if not found).
fn kernel_body<'a>(source: &'a str, name: &str) -> &'a str {
    // The declaration: `__global__`, then (qualifiers such as `__launch_bounds__(...)` and)
    // the name followed by `(`, without a brace or semicolon between them.
    let key = format!(" {name}(");
    let start = source.match_indices(&key).map(|(i, _)| i).find(|&i| {
        source[..i]
            .rfind("__global__")
            .is_some_and(|g| !source[g..i].contains(['{', '}', ';']))
    });
    let Some(start) = start else {
        return "";
    };
    let rest = &source[start..];
    let Some(open) = rest.find('{') else {
        return "";
    };
    let mut depth = 0usize;
    for (i, c) in rest[open..].char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return &rest[open..=open + i];
                }
            }
            _ => {}
        }
    }
    &rest[open..]
}

/// Whether kernel `name` cooperates within its block: its body declares `__shared__` memory or
/// calls `__syncthreads` (a helper may hold the barrier; calling it from a kernel run in turn
/// aborts with a message instead of hanging).
fn is_threaded(source: &str, name: &str) -> bool {
    let body = kernel_body(source, name);
    body.contains("__shared__") || body.contains("__syncthreads")
}

/// The compiled kernels: entry points and parameter signatures.
pub(crate) struct Host {
    /// One launch at a time: the emulated kernels share the library's globals (thread indices'
    /// dimensions, the block barrier, shared memory).
    running: std::sync::Mutex<()>,
    compiler: String,
    kernels: HashMap<String, (Run, String)>,
    shuffle: unsafe extern "C" fn(u64),
    // Keeps the entry points valid; dropped before the directory holding it.
    _lib: libloading::Library,
    _dir: tempfile::TempDir,
}

impl std::fmt::Debug for Host {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// A C++ compiler: the command and what its `--version` says.
pub(crate) struct Compiler {
    pub(crate) command: String,
    pub(crate) version: String,
}

/// The first of `candidates` whose `--version` runs, with what it printed.
pub(crate) fn first_that_runs(candidates: &[String]) -> Option<Compiler> {
    candidates.iter().find_map(|c| {
        let out = Command::new(c).arg("--version").output().ok()?;
        out.status.success().then(|| Compiler {
            command: c.clone(),
            version: String::from_utf8_lossy(&out.stdout).trim().to_string(),
        })
    })
}

/// The C++ compiler: `$CXX`, else the first of `c++`, `g++`, `clang++` that runs.
fn compiler() -> Result<Compiler, GpuError> {
    let candidates: Vec<String> = match std::env::var("CXX") {
        Ok(c) if !c.is_empty() => vec![c],
        _ => ["c++", "g++", "clang++"].map(String::from).to_vec(),
    };
    first_that_runs(&candidates).ok_or_else(|| {
        GpuError::NoDevice(format!(
            "the host emulation needs a C++ compiler and none of {} runs",
            candidates.join(", ")
        ))
    })
}

/// The compiler's flags. No fused multiply-adds (NVRTC compiles with `fmad` off too): the
/// kernels' results are then the CPU's bits where they do the CPU's arithmetic in its order,
/// on hosts whose compilers would fuse by default (aarch64).
const FLAGS: [&str; 6] = [
    "-std=c++17",
    "-O2",
    "-ffp-contract=off",
    "-fPIC",
    "-shared",
    "-pthread",
];

/// What identifies a compiled library: the compiler (command and version), the flags, the
/// machine and the whole text.
fn library_key(compiler: &Compiler, text: &str) -> String {
    format!(
        "{}\n{}\n{}\n{}-{}\n{text}",
        compiler.command,
        compiler.version,
        FLAGS.join(" "),
        std::env::consts::ARCH,
        std::env::consts::OS
    )
}

/// A library's place in [`COMPILED`]: empty until the first device that needs it has it.
type Slot = std::sync::Arc<std::sync::Mutex<Option<std::sync::Arc<Vec<u8>>>>>;

/// The libraries compiled so far in this process, by [`library_key`]: another device with the
/// same kernels loads a copy of the same bytes (a file of its own, so that it has its own
/// globals: the dynamic loader would share one library between two loads of one file) instead
/// of compiling again, which takes seconds per kernel set. Devices opened together with the
/// same kernels wait for one compilation (the slot's lock); different kernels compile side by
/// side.
static COMPILED: std::sync::Mutex<Vec<(String, Slot)>> = std::sync::Mutex::new(Vec::new());

/// The shared library of `text` compiled by `compiler`: from [`COMPILED`], else from the disk
/// cache, else compiled now in `dir`.
fn library_bytes(
    compiler: &Compiler,
    text: &str,
    dir: &std::path::Path,
) -> Result<std::sync::Arc<Vec<u8>>, GpuError> {
    let key = library_key(compiler, text);
    let slot = {
        let mut all = COMPILED
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match all.iter().find(|(k, _)| *k == key) {
            Some((_, s)) => s.clone(),
            None => {
                let s = Slot::default();
                all.push((key.clone(), s.clone()));
                s
            }
        }
    };
    let mut held = slot
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(bytes) = held.as_ref() {
        return Ok(bytes.clone());
    }
    let on_disk = DiskCache::from_env(&key);
    let bytes = match on_disk.as_ref().and_then(DiskCache::read) {
        Some(bytes) => bytes,
        None => {
            let bytes = compile_library(compiler, text, dir)?;
            if let Some(disk) = &on_disk {
                disk.write(&bytes);
            }
            bytes
        }
    };
    let bytes = std::sync::Arc::new(bytes);
    *held = Some(bytes.clone());
    Ok(bytes)
}

/// `text` compiled by `compiler` into a shared library, in the folder `dir`: its bytes.
fn compile_library(
    compiler: &Compiler,
    text: &str,
    dir: &std::path::Path,
) -> Result<Vec<u8>, GpuError> {
    let lib = dir.join("compiled.so");
    compile_file(
        &compiler.command,
        &FLAGS,
        text,
        &dir.join("kernels.cpp"),
        &lib,
    )?;
    std::fs::read(&lib).map_err(|e| GpuError::Compile(format!("reading {}: {e}", lib.display())))
}

/// `text` written to `src` and compiled by `command` with `flags` into `out`; the compiler's
/// messages in the error where it fails.
pub(crate) fn compile_file(
    command: &str,
    flags: &[&str],
    text: &str,
    src: &std::path::Path,
    out: &std::path::Path,
) -> Result<(), GpuError> {
    std::fs::write(src, text)
        .map_err(|e| GpuError::Compile(format!("writing {}: {e}", src.display())))?;
    let run = Command::new(command)
        .args(flags)
        .arg("-o")
        .arg(out)
        .arg(src)
        .output()
        .map_err(|e| GpuError::Compile(format!("running {command}: {e}")))?;
    if !run.status.success() {
        return Err(GpuError::Compile(format!(
            "{command} {} failed:\n{}",
            flags.join(" "),
            String::from_utf8_lossy(&run.stderr)
        )));
    }
    Ok(())
}

/// Compiled libraries kept between processes, in the folder `MOTILE_EMULATION_CACHE` names
/// (unset: none; the test script sets it, as the runs it checks start many processes): a
/// library is one file `<hash>.lib`, its whole [`library_key`] (compiler, version, flags,
/// machine, text) and its length, then the library's bytes; it is used only where the key
/// matches (the hash only names the file). Written atomically (synced, then renamed); a cache
/// that cannot be read or written is passed over (the kernels are then compiled).
struct DiskCache {
    path: std::path::PathBuf,
    key: String,
}

impl DiskCache {
    fn from_env(key: &str) -> Option<Self> {
        let dir = std::path::PathBuf::from(std::env::var_os("MOTILE_EMULATION_CACHE")?);
        (!dir.as_os_str().is_empty()).then(|| Self::new(&dir, key))
    }

    fn new(dir: &std::path::Path, key: &str) -> Self {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        key.hash(&mut h);
        Self {
            path: dir.join(format!("{:016x}.lib", h.finish())),
            key: key.to_string(),
        }
    }

    fn read(&self) -> Option<Vec<u8>> {
        let file = std::fs::read(&self.path).ok()?;
        let (len, rest) = file.split_first_chunk::<8>()?;
        let len = usize::try_from(u64::from_le_bytes(*len)).ok()?;
        (rest.get(..len)? == self.key.as_bytes()).then(|| rest[len..].to_vec())
    }

    fn write(&self, bytes: &[u8]) {
        let write = || -> std::io::Result<()> {
            let dir = self.path.parent().unwrap_or(std::path::Path::new("."));
            std::fs::create_dir_all(dir)?;
            let mut tmp = tempfile::NamedTempFile::new_in(dir)?;
            let key = self.key.as_bytes();
            for part in [&(key.len() as u64).to_le_bytes()[..], key, bytes] {
                std::io::Write::write_all(&mut tmp, part)?;
            }
            tmp.as_file().sync_all()?;
            tmp.persist(&self.path).map_err(|e| e.error)?;
            Ok(())
        };
        // Best effort: the kernels are compiled again where the file is missing.
        let _ = write();
    }
}

impl Host {
    pub(crate) fn compile(source: &str, kernels: &[&str]) -> Result<Self, GpuError> {
        let compiler = compiler()?;
        let dir = tempfile::tempdir()
            .map_err(|e| GpuError::Compile(format!("a scratch directory: {e}")))?;
        let lib = dir.path().join("libkernels.so");
        let mut text = String::from(PRELUDE);
        text.push_str("#line 1 \"kernels.cu\"\n");
        text.push_str(source);
        text.push('\n');
        // Kernels that synchronise their blocks run threaded.
        for k in kernels {
            let threaded = is_threaded(source, k);
            text.push_str(&format!("MOTILE_ENTRY({k}, {threaded})\n"));
        }
        let bytes = library_bytes(&compiler, &text, dir.path())?;
        std::fs::write(&lib, bytes.as_slice())
            .map_err(|e| GpuError::Compile(format!("writing {}: {e}", lib.display())))?;
        // SAFETY: the library was built from the prelude and the kernel source (now, or by
        // this compiler with these flags from this text earlier: `library_bytes`); loading
        // it runs only the C++ runtime's static initialisers (the kernels have none).
        let library = unsafe { libloading::Library::new(&lib) }
            .map_err(|e| GpuError::Compile(format!("loading the emulated kernels: {e}")))?;
        let mut map = HashMap::new();
        for k in kernels {
            let missing = |e: libloading::Error| GpuError::Compile(format!("kernel {k}: {e}"));
            // SAFETY: MOTILE_ENTRY defines both symbols with exactly these C signatures.
            let (run, sig) = unsafe {
                let run: libloading::Symbol<Run> = library
                    .get(format!("motile_run_{k}").as_bytes())
                    .map_err(missing)?;
                let sig: libloading::Symbol<Sig> = library
                    .get(format!("motile_sig_{k}").as_bytes())
                    .map_err(missing)?;
                (*run, *sig)
            };
            // SAFETY: motile_sig_* returns a pointer to a static NUL-terminated string.
            let signature = unsafe { CStr::from_ptr(sig()) }
                .to_string_lossy()
                .into_owned();
            map.insert((*k).to_string(), (run, signature));
        }
        // SAFETY: the prelude defines motile_set_shuffle with this C signature.
        let shuffle = unsafe {
            *library
                .get::<unsafe extern "C" fn(u64)>(b"motile_set_shuffle")
                .map_err(|e| GpuError::Compile(format!("motile_set_shuffle: {e}")))?
        };
        Ok(Self {
            running: std::sync::Mutex::new(()),
            compiler: compiler.command,
            kernels: map,
            shuffle,
            _lib: library,
            _dir: dir,
        })
    }

    /// Run blocks in a new random order at every launch (`seed` nonzero), or in turn (0).
    pub(crate) fn shuffle_blocks(&self, seed: u64) {
        let _one_at_a_time = self
            .running
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        // SAFETY: sets a global of the library that only launches read, none running (lock).
        unsafe { (self.shuffle)(seed) }
    }

    pub(crate) fn describe(&self) -> String {
        format!(
            "host emulation ({} kernels compiled by {})",
            self.kernels.len(),
            self.compiler
        )
    }

    /// # Safety
    /// As `Device::launch` (the types are checked here; the indices are not).
    pub(crate) unsafe fn launch(
        &self,
        kernel: &str,
        blocks: u32,
        args: &mut [Arg<'_>],
    ) -> Result<(), GpuError> {
        let (run, signature) = self
            .kernels
            .get(kernel)
            .ok_or_else(|| GpuError::Input(format!("no kernel {kernel} was compiled")))?;
        let given: String = args.iter().map(Arg::code).collect();
        if &given != signature {
            return Err(GpuError::Input(format!(
                "kernel {kernel} takes parameters ({signature}) but was given ({given}) \
                 (the codes of motile_gpu::c_type_code)"
            )));
        }
        // Each parameter's value in an aligned 8-byte slot, then a pointer to it (CUDA's
        // kernelParams convention).
        let mut values: Vec<u64> = Vec::with_capacity(args.len());
        for a in args.iter_mut() {
            let slot = match a {
                Arg::InF64(b) => host_ptr(&b.data)?,
                Arg::OutF64(b) => host_ptr_mut(&mut b.data)?,
                Arg::InI32(b) => host_ptr(&b.data)?,
                Arg::OutI32(b) => host_ptr_mut(&mut b.data)?,
                Arg::InU32(b) => host_ptr(&b.data)?,
                Arg::OutU32(b) => host_ptr_mut(&mut b.data)?,
                Arg::Int(i) => {
                    let mut w = [0u8; 8];
                    w[..4].copy_from_slice(&i.to_ne_bytes());
                    u64::from_ne_bytes(w)
                }
                Arg::Real(x) => x.to_bits(),
                Arg::Long(i) => *i as u64,
            };
            values.push(slot);
        }
        let mut params: Vec<*mut c_void> = values
            .iter_mut()
            .map(|v| std::ptr::from_mut(v).cast::<c_void>())
            .collect();
        let _one_at_a_time = self
            .running
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        // SAFETY: the parameter types match the kernel's (checked above); each params entry
        // points to 8 bytes holding the value (a pointer into a live host buffer, an int in
        // its first four bytes, or a double), which outlive the call; no other launch runs
        // (the lock); the indices the kernel touches are the caller's contract.
        unsafe { run(blocks, THREADS, params.as_mut_ptr()) };
        Ok(())
    }
}

/// The address of a host buffer's values, as a kernel parameter slot.
fn host_ptr<T: crate::buffer::Element>(d: &Data<T>) -> Result<u64, GpuError> {
    match d {
        Data::Host(v) => Ok(v.as_ptr() as usize as u64),
        #[allow(unreachable_patterns)]
        _ => Err(GpuError::foreign()),
    }
}

/// [`host_ptr`] of a buffer the kernel writes.
fn host_ptr_mut<T: crate::buffer::Element>(d: &mut Data<T>) -> Result<u64, GpuError> {
    match d {
        Data::Host(v) => Ok(v.as_mut_ptr() as usize as u64),
        #[allow(unreachable_patterns)]
        _ => Err(GpuError::foreign()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_with_block_cooperation_are_found_by_their_bodies() {
        let src = r#"
__device__ void helper() { __syncthreads(); }
extern "C" __global__ void plain(double* x) { x[threadIdx.x] = 1.0; }
extern "C" __global__ void __launch_bounds__(256) tiled(double* x) {
    __shared__ double t[256];
    if (threadIdx.x == 0) { t[0] = 1.0; }
    helper();
    x[0] = t[0];
}
extern "C" __global__ void synced(double* x) { __syncthreads(); }
"#;
        assert!(!is_threaded(src, "plain"));
        assert!(is_threaded(src, "tiled"));
        assert!(is_threaded(src, "synced"));
        assert!(kernel_body(src, "tiled").ends_with("x[0] = t[0];\n}"));
        assert_eq!(kernel_body(src, "missing"), "");
    }

    /// The disk cache gives back what was written for the same key (compiler, version, flags,
    /// machine, text), and nothing for another key, even one whose file has the same name (a
    /// hash collision), nor from a file cut short.
    #[test]
    fn the_disk_cache_returns_a_library_only_for_its_own_key() {
        let dir = tempfile::tempdir().unwrap();
        let gcc = |version: &str| Compiler {
            command: "c++".into(),
            version: version.into(),
        };
        let key = |c: &Compiler, text: &str| library_key(c, text);
        let a = DiskCache::new(dir.path(), &key(&gcc("12.2"), "text a"));
        assert!(a.read().is_none(), "an empty cache");
        a.write(b"library a");
        assert_eq!(a.read().as_deref(), Some(&b"library a"[..]));
        let again = DiskCache::new(dir.path(), &key(&gcc("12.2"), "text a"));
        assert_eq!(again.read().as_deref(), Some(&b"library a"[..]));
        let clang = Compiler {
            command: "clang++".into(),
            version: "12.2".into(),
        };
        for (what, other) in [
            ("another compiler", key(&clang, "text a")),
            ("another version", key(&gcc("13.1"), "text a")),
            ("another text", key(&gcc("12.2"), "text b")),
        ] {
            let c = DiskCache::new(dir.path(), &other);
            assert!(c.read().is_none(), "{what}: a library found");
            // A collision: the other key under the same file name.
            let mut c = c;
            c.path = a.path.clone();
            assert!(
                c.read().is_none(),
                "{what} under a colliding name: a library found"
            );
        }
        // A file cut short (its key not whole): no library.
        let file = std::fs::read(&a.path).unwrap();
        std::fs::write(&a.path, &file[..20]).unwrap();
        assert!(a.read().is_none(), "a file cut short");
    }
}
