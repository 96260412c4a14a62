//! Device buffers typed by their elements: `f64` (a kernel's `double*`, or `double2*` for
//! interleaved complex values), `i32` (`int*`) and `u32` (`unsigned int*`), so that integers
//! stay integers on the device.

use std::sync::atomic::{AtomicUsize, Ordering};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for i32 {}
    impl Sealed for u32 {}
}

/// What a CUDA buffer needs of its elements (nothing without the `cuda` feature).
#[cfg(feature = "cuda")]
#[doc(hidden)]
pub trait DeviceValue:
    cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Unpin
{
}
#[cfg(feature = "cuda")]
impl<T: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Unpin> DeviceValue for T {}
/// What a CUDA buffer needs of its elements (nothing without the `cuda` feature).
#[cfg(not(feature = "cuda"))]
#[doc(hidden)]
pub trait DeviceValue {}
#[cfg(not(feature = "cuda"))]
impl<T> DeviceValue for T {}

/// The element types of device buffers: `f64`, `i32`, `u32` (sealed).
pub trait Element:
    sealed::Sealed + DeviceValue + Copy + Default + PartialEq + std::fmt::Debug + Send + Sync + 'static
{
    /// The C type a kernel's pointer parameter to these elements has.
    const C_TYPE: &'static str;
}

impl Element for f64 {
    const C_TYPE: &'static str = "double";
}

impl Element for i32 {
    const C_TYPE: &'static str = "int";
}

impl Element for u32 {
    const C_TYPE: &'static str = "unsigned int";
}

/// A buffer of `T` on a device (complex values as interleaved `f64` pairs).
#[derive(Debug)]
pub struct Buffer<T: Element = f64> {
    pub(crate) len: usize,
    pub(crate) data: Data<T>,
}

impl<T: Element> Drop for Buffer<T> {
    fn drop(&mut self) {
        LIVE.fetch_sub(Self::bytes(self.len), Ordering::Relaxed);
    }
}

#[derive(Debug)]
pub(crate) enum Data<T: Element> {
    Host(Vec<T>),
    #[cfg(feature = "cuda")]
    Cuda(cudarc::driver::CudaSlice<T>),
}

/// Bytes of the buffers alive in this process (all devices), and the most there have been
/// since the last [`reset_peak`]: a tally that needs no device (the host emulation's buffers
/// count as CUDA's would), for memory budgets measured without a GPU and for breaking down a
/// GPU's use. A CUDA buffer of no values counts the one value the driver is asked for.
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

/// Bytes of the device buffers alive now (every device of the process; FFT plans' work areas
/// and the driver's own memory apart).
pub fn live_bytes() -> usize {
    LIVE.load(Ordering::Relaxed)
}

/// The most bytes of device buffers alive at once since the last [`reset_peak`] (or since the
/// process started).
pub fn peak_bytes() -> usize {
    PEAK.load(Ordering::Relaxed)
}

/// Start a new peak at the bytes alive now.
pub fn reset_peak() {
    PEAK.store(LIVE.load(Ordering::Relaxed), Ordering::Relaxed);
}

impl<T: Element> Buffer<T> {
    /// Wrap `data` of `len` values, counted in the tally.
    pub(crate) fn new(len: usize, data: Data<T>) -> Self {
        let now = LIVE.fetch_add(Self::bytes(len), Ordering::Relaxed) + Self::bytes(len);
        PEAK.fetch_max(now, Ordering::Relaxed);
        Self { len, data }
    }

    fn bytes(len: usize) -> usize {
        len.max(1) * std::mem::size_of::<T>()
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no values.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// An error naming `what` where `buf` holds fewer than `at_least` values: the length check
/// before a launch whose kernel reads or writes that many.
pub fn check_len<T: Element>(
    what: &str,
    buf: &Buffer<T>,
    at_least: usize,
) -> Result<(), crate::error::GpuError> {
    if buf.len() < at_least {
        return Err(crate::error::GpuError::Input(format!(
            "{what}: {} values where the kernel reads or writes {at_least}",
            buf.len()
        )));
    }
    Ok(())
}
