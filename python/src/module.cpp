// The compiled part of the `shinevdb` package (python/shinevdb/__init__.py re-exports it).
#include <pybind11/pybind11.h>

#include "shine/core/error.hpp"

namespace shinevdb {
namespace py = pybind11;
void bind_neural_map(py::module_& m);
void bind_tsdf_volume(py::module_& m);
void bind_sequence_eval(py::module_& m);
void bind_mesh(py::module_& m);
}  // namespace shinevdb

PYBIND11_MODULE(_shinevdb, m) {
    namespace py = pybind11;
    m.doc() = "ShineVDB: neural SDF mapping (SHINE-Mapping) and a TSDF baseline on OpenVDB.";
    // shine::Error's family as Python's usual exceptions: bad values and inconsistent data are
    // ValueError, files OSError, a stop request KeyboardInterrupt.
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const shine::ConfigError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const shine::DataError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const shine::IoError& e) {
            PyErr_SetString(PyExc_OSError, e.what());
        } catch (const shine::Interrupted& e) {
            PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
        } catch (const shine::Error& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });
    shinevdb::bind_mesh(m);  // first: NeuralMap.extract_mesh's signature names shinevdb.Mesh
    shinevdb::bind_neural_map(m);
    shinevdb::bind_tsdf_volume(m);
    shinevdb::bind_sequence_eval(m);
}
