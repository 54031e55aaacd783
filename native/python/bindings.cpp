// Module definition: exceptions and the shared matrix conversions; the API lives in bind_*.cpp.
#include "bindings.h"

#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <string>

#include "pcvr/errors.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace pcvr::python {

Mat4 mat4_from_python(nb::handle obj, const char* what) {
    // Go through numpy so every array-like (lists, mathutils.Matrix, numpy arrays) is accepted.
    nb::module_ np = nb::module_::import_("numpy");
    nb::object arr;
    try {
        arr = np.attr("asarray")(obj, "dtype"_a = "float64");
    } catch (nb::python_error&) {
        throw nb::value_error((std::string(what) + " must be a 4x4 matrix of numbers").c_str());
    }
    nb::tuple shape = nb::tuple(arr.attr("shape"));
    if (nb::len(shape) != 2 || nb::cast<int>(shape[0]) != 4 || nb::cast<int>(shape[1]) != 4)
        throw nb::value_error((std::string(what) + " must have shape (4, 4), got " +
                               nb::cast<std::string>(nb::str(shape))).c_str());
    Mat4 out;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            // Non-finite values are left to the receiving type, which names the real problem
            // (a camera or a grid transform).
            out.m[i][j] = nb::cast<double>(arr[nb::make_tuple(i, j)]);
        }
    return out;
}

nb::object mat4_to_numpy(const Mat4& m) {
    auto* data = new double[16];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) data[i * 4 + j] = m.m[i][j];
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<double*>(p); });
    return nb::cast(nb::ndarray<nb::numpy, double, nb::shape<4, 4>>(data, {4, 4}, owner));
}

}  // namespace pcvr::python

NB_MODULE(_pcvr, m) {
    using namespace nb::literals;
    m.doc() = "PCVR native core: post-convolved splatting of OpenVDB volumes";

    // Exception types: each C++ error class maps to one Python class with a natural builtin base.
    nb::register_exception_translator([](const std::exception_ptr& p, void*) {
        // Registered first, so nanobind tries it after the specific classes below.
        try {
            std::rethrow_exception(p);
        } catch (const pcvr::FileNotFound& e) {
            PyErr_SetString(PyExc_FileNotFoundError, e.what());
        } catch (const pcvr::InvalidArgument& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const pcvr::OutOfMemory& e) {
            PyErr_SetString(PyExc_MemoryError, e.what());
        } catch (const pcvr::Error& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });

    nb::exception<pcvr::VdbReadError>(m, "VDBReadError", PyExc_OSError);
    nb::exception<pcvr::GridError>(m, "GridError", PyExc_ValueError);
    nb::exception<pcvr::CameraError>(m, "CameraError", PyExc_ValueError);
    nb::exception<pcvr::Cancelled>(m, "RenderCancelled", PyExc_RuntimeError);

    pcvr::python::bind_grid(m);
    pcvr::python::bind_render(m);
    pcvr::python::bind_shaded(m);
}
