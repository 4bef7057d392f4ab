// The extension module incise._incise (re-exported by incise/__init__.py). Errors are the
// library's exception hierarchy, with the messages the CLI prints after "incise: error: ".
#include "python/bindings.h"

#include "mesh/errors.h"

namespace incise::python {

void bind_errors(py::module_& m) {
  // Translators run most recent first: register the base class before the derived ones.
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<IoError> io_error(m, "IoError", error.ptr());
  static py::exception<InvalidMesh> invalid_mesh(m, "InvalidMesh", error.ptr());
  static py::exception<InvalidArgument> invalid_argument(m, "InvalidArgument", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const IoError& e) {
      io_error(e.what());
    } catch (const InvalidMesh& e) {
      invalid_mesh(e.what());
    } catch (const InvalidArgument& e) {
      invalid_argument(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });
}

}  // namespace incise::python

PYBIND11_MODULE(_incise, m) {
  using namespace incise::python;
  m.doc() = "incise: tetrahedral meshing, quality, cutting and simulation of soft tissue";
  bind_errors(m);
  bind_mesh(m);
  bind_io(m);
  bind_quality(m);
  bind_sim(m);
  bind_cut(m);
  bind_improve(m);
#ifdef INCISE_HAVE_TETRA
  bind_tetra(m);
  m.attr("have_tetra") = true;
#else
  m.attr("have_tetra") = false;
#endif
}
