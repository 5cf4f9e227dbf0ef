//! Numpy arrays over shared memory. A [`Loan`] holds a sample the server
//! lent (a frame, a capture); an array made over it has the loan as its
//! base object, so the sample stays lent while any array views it, and the
//! array never reads memory that went back to the server. The arrays are
//! read-only: the server's samples are mapped read-only in a client.

use std::ops::Range;

use numpy::ndarray::ArrayView1;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A sample lent by the server: what numpy arrays over shared memory keep
/// alive. Bound to the thread that received it (iceoryx2's samples are).
#[pyclass(module = "simbus", unsendable)]
pub(crate) struct Loan {
    pub(crate) sample: Lent,
}

/// What a [`Loan`] holds.
pub(crate) enum Lent {
    /// A frame's snapshot.
    Frame(sim_client::FrameView),
    /// A sensor capture.
    Capture(sim_client::Capture),
}

impl std::fmt::Debug for Loan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.sample {
            Lent::Frame(view) => write!(f, "Loan(frame {})", view.frame()),
            Lent::Capture(capture) => write!(f, "Loan(capture {})", capture.header().sequence),
        }
    }
}

#[pymethods]
impl Loan {
    fn __repr__(&self) -> String {
        format!("<simbus {self:?}>")
    }
}

impl Loan {
    /// The bytes of the sample's payload.
    fn bytes(&self) -> &[u8] {
        match &self.sample {
            Lent::Frame(view) => view.payload_bytes(),
            Lent::Capture(capture) => capture.bytes(),
        }
    }
}

/// Gives `loan` back (empties it) unless numpy arrays still view it: then
/// `BufferError` naming `what` (Python's `memoryview.release()` rule), and
/// the loan stays.
pub(crate) fn give_back(
    loan: &mut Option<Py<Loan>>,
    what: impl FnOnce() -> String,
) -> PyResult<()> {
    let views = loan.as_ref().map_or(0, |loan| {
        // SAFETY: `loan` is a live object (the caller holds a reference).
        unsafe { pyo3::ffi::Py_REFCNT(loan.as_ptr()) - 1 }
    });
    if views > 0 {
        return Err(pyo3::exceptions::PyBufferError::new_err(format!(
            "{views} numpy array(s) still view {}: delete them, or copy() them first",
            what()
        )));
    }
    *loan = None;
    Ok(())
}

/// A read-only `uint8` array over `loan`'s payload, its base the loan.
pub(crate) fn bytes_of<'py>(loan: &Bound<'py, Loan>) -> PyResult<Bound<'py, PyArray1<u8>>> {
    let len = loan.borrow().bytes().len();
    part_of(loan, 0..len)
}

/// A read-only `uint8` array over `range` of `loan`'s payload (empty where
/// the payload is shorter), its base the loan.
fn part_of<'py>(
    loan: &Bound<'py, Loan>,
    range: Range<usize>,
) -> PyResult<Bound<'py, PyArray1<u8>>> {
    let borrowed = loan.borrow();
    let bytes = borrowed.bytes().get(range).unwrap_or_default();
    let view = ArrayView1::from(bytes);
    // SAFETY: the array views memory the loan owns (the sample's payload in
    // shared memory, mapped for as long as the sample lives); the loan is
    // the array's base object, so it outlives the array, and nothing
    // changes the payload while it is lent (the server writes a sample
    // only before it sends it).
    let array = unsafe { PyArray1::borrow_from_array(&view, loan.clone().into_any()) };
    drop(borrowed);
    array.call_method1("setflags", (false,))?;
    Ok(array)
}

/// A read-only one-dimensional array of `dtype` elements over `range` of
/// `loan`'s payload (its base chain ends at the loan).
pub(crate) fn view_as<'py>(
    loan: &Bound<'py, Loan>,
    range: Range<usize>,
    dtype: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    part_of(loan, range)?.call_method1("view", (dtype,))
}

/// A numpy structured dtype from `(name, format, offset)` fields and the
/// record's size.
pub(crate) fn structured_dtype<'py>(
    py: Python<'py>,
    fields: &[(&str, &str, usize)],
    itemsize: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = PyDict::new(py);
    spec.set_item("names", fields.iter().map(|f| f.0).collect::<Vec<_>>())?;
    spec.set_item("formats", fields.iter().map(|f| f.1).collect::<Vec<_>>())?;
    spec.set_item("offsets", fields.iter().map(|f| f.2).collect::<Vec<_>>())?;
    spec.set_item("itemsize", itemsize)?;
    py.import("numpy")?.getattr("dtype")?.call1((spec,))
}
