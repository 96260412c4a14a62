//! The host emulation: kernels compiled by the system's C++ compiler with a prelude that
//! defines CUDA's built-ins, loaded as a shared library, every thread run in turn.
#![allow(unsafe_code)]

use crate::buffer::Data;
use crate::error::GpuError;
use crate::kernel::{Arg, THREADS};
use std::collections::HashMap;
use std::ffi::{CStr, c_char, c_void};
use std::process::Command;

/// What the kernels see of CUDA: thread indices (one thread at a time, so a plain global is
/// enough), qualifiers as no-ops, `atomicAdd` as a plain add (nothing runs concurrently), and
/// per kernel an entry point that runs every thread of every block and one that describes its
/// parameter types (the codes of `kernel::c_type_code`). Shared memory and `__syncthreads` run each block's threads as OS
/// threads with a barrier (the source is compiled that way when it uses `__syncthreads`).
const PRELUDE: &str = r#"
#include <cmath>
#include <math.h>
#include <cstddef>
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
static inline double atomicAdd(double* p, double v) {
    static std::mutex m;
    std::lock_guard<std::mutex> g(m);
    double old = *p;
    *p = old + v;
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
#define __syncthreads() motile_block_barrier.wait()
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
// Every thread of every block. Kernels without __syncthreads run their threads one after
// another on the calling thread; with it (MOTILE_THREADED), each thread of a block is an OS
// thread, the blocks one after another, a barrier between blocks.
template <typename... A>
static void motile_launch(void (*f)(A...), unsigned grid, unsigned block, void** a) {
    gridDim = {grid, 1, 1};
    blockDim = {block, 1, 1};
#ifdef MOTILE_THREADED
    motile_block_barrier.count = block;
    std::vector<std::thread> threads;
    for (unsigned t = 0; t < block; ++t) {
        threads.emplace_back([=] {
            for (unsigned b = 0; b < grid; ++b) {
                blockIdx = {b, 0, 0};
                threadIdx = {t, 0, 0};
                motile_call(f, a, std::index_sequence_for<A...>{});
                motile_block_barrier.wait();
            }
        });
    }
    for (auto& th : threads) th.join();
#else
    for (unsigned b = 0; b < grid; ++b) {
        for (unsigned t = 0; t < block; ++t) {
            blockIdx = {b, 0, 0};
            threadIdx = {t, 0, 0};
            motile_call(f, a, std::index_sequence_for<A...>{});
        }
    }
#endif
}
#define MOTILE_ENTRY(name) \
    extern "C" void motile_run_##name(unsigned g, unsigned b, void** a) { motile_launch(name, g, b, a); } \
    extern "C" const char* motile_sig_##name() { return motile_signature(name); }
"#;

// Pointers travel in 8-byte slots.
const _: () = assert!(std::mem::size_of::<usize>() == 8);

type Run = unsafe extern "C" fn(u32, u32, *mut *mut c_void);
type Sig = unsafe extern "C" fn() -> *const c_char;

/// The compiled kernels: entry points and parameter signatures.
pub(crate) struct Host {
    /// One launch at a time: the emulated kernels share the library's globals (thread indices'
    /// dimensions, the block barrier, shared memory).
    running: std::sync::Mutex<()>,
    compiler: String,
    kernels: HashMap<String, (Run, String)>,
    // Keeps the entry points valid; dropped before the directory holding it.
    _lib: libloading::Library,
    _dir: tempfile::TempDir,
}

impl std::fmt::Debug for Host {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// The C++ compiler: `$CXX`, else the first of `c++`, `g++`, `clang++` that runs.
fn compiler() -> Result<String, GpuError> {
    let candidates: Vec<String> = match std::env::var("CXX") {
        Ok(c) if !c.is_empty() => vec![c],
        _ => ["c++", "g++", "clang++"].map(String::from).to_vec(),
    };
    candidates
        .iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .cloned()
        .ok_or_else(|| {
            GpuError::NoDevice(format!(
                "the host emulation needs a C++ compiler and none of {} runs",
                candidates.join(", ")
            ))
        })
}

impl Host {
    pub(crate) fn compile(source: &str, kernels: &[&str]) -> Result<Self, GpuError> {
        let compiler = compiler()?;
        let dir = tempfile::tempdir()
            .map_err(|e| GpuError::Compile(format!("a scratch directory: {e}")))?;
        let src = dir.path().join("kernels.cpp");
        let lib = dir.path().join("libkernels.so");
        // Kernels that synchronise their blocks need the threaded launches.
        let mut text = if source.contains("__syncthreads") {
            String::from("#define MOTILE_THREADED 1\n")
        } else {
            String::new()
        };
        text.push_str(PRELUDE);
        text.push_str("#line 1 \"kernels.cu\"\n");
        text.push_str(source);
        text.push('\n');
        for k in kernels {
            text.push_str(&format!("MOTILE_ENTRY({k})\n"));
        }
        std::fs::write(&src, text)
            .map_err(|e| GpuError::Compile(format!("writing {}: {e}", src.display())))?;
        let out = Command::new(&compiler)
            .args(["-std=c++17", "-O2", "-fPIC", "-shared", "-pthread", "-o"])
            .arg(&lib)
            .arg(&src)
            .output()
            .map_err(|e| GpuError::Compile(format!("running {compiler}: {e}")))?;
        if !out.status.success() {
            return Err(GpuError::Compile(format!(
                "{compiler} failed:\n{}",
                String::from_utf8_lossy(&out.stderr)
            )));
        }
        // SAFETY: the library was just built from the prelude and the kernel source; loading
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
        Ok(Self {
            running: std::sync::Mutex::new(()),
            compiler,
            kernels: map,
            _lib: library,
            _dir: dir,
        })
    }

    pub(crate) fn describe(&self) -> String {
        format!(
            "host emulation ({} kernels compiled by {}, one thread at a time)",
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
