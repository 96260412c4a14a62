//! Device buffers typed by their elements: `f64` (a kernel's `double*`, or `double2*` for
//! interleaved complex values), `i32` (`int*`) and `u32` (`unsigned int*`), so that integers
//! stay integers on the device.

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

#[derive(Debug)]
pub(crate) enum Data<T: Element> {
    Host(Vec<T>),
    #[cfg(feature = "cuda")]
    Cuda(cudarc::driver::CudaSlice<T>),
}

impl<T: Element> Buffer<T> {
    /// Number of values.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no values.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}
