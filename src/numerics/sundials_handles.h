// Move-only owners of SUNDIALS C handles (STYLE.md: every C handle has one RAII owner and the
// free calls appear only here). SUNDIALS 6.x API.
#pragma once

#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <stdexcept>
#include <utility>

namespace millkit::numerics {

template <typename Handle, void (*Free)(Handle*)>
class SundialsHandle {
 public:
  SundialsHandle() = default;
  explicit SundialsHandle(Handle handle) : handle_(handle) {
    if (handle_ == nullptr) throw std::runtime_error("SUNDIALS allocation failed");
  }
  ~SundialsHandle() {
    if (handle_ != nullptr) Free(&handle_);
  }
  SundialsHandle(SundialsHandle&& other) noexcept
      : handle_(std::exchange(other.handle_, nullptr)) {}
  SundialsHandle& operator=(SundialsHandle&& other) noexcept {
    if (this != &other) {
      if (handle_ != nullptr) Free(&handle_);
      handle_ = std::exchange(other.handle_, nullptr);
    }
    return *this;
  }
  SundialsHandle(const SundialsHandle&) = delete;
  SundialsHandle& operator=(const SundialsHandle&) = delete;
  Handle get() const { return handle_; }

 private:
  Handle handle_ = nullptr;
};

namespace detail {
inline void FreeContext(SUNContext* c) { SUNContext_Free(c); }
inline void FreeVector(N_Vector* v) { N_VDestroy(*v); }
inline void FreeMatrix(SUNMatrix* m) { SUNMatDestroy(*m); }
inline void FreeLinearSolver(SUNLinearSolver* s) { SUNLinSolFree(*s); }
inline void FreeCvode(void** mem) { CVodeFree(mem); }
}  // namespace detail

using SundialsVector = SundialsHandle<N_Vector, detail::FreeVector>;
using SundialsMatrix = SundialsHandle<SUNMatrix, detail::FreeMatrix>;
using SundialsLinearSolver = SundialsHandle<SUNLinearSolver, detail::FreeLinearSolver>;
using CvodeMemory = SundialsHandle<void*, detail::FreeCvode>;

class SundialsContext {
 public:
  SundialsContext() {
    SUNContext context = nullptr;
    if (SUNContext_Create(nullptr, &context) != 0) {
      throw std::runtime_error("SUNContext_Create failed");
    }
    handle_ = Handle(context);
  }
  SUNContext get() const { return handle_.get(); }

 private:
  using Handle = SundialsHandle<SUNContext, detail::FreeContext>;
  Handle handle_;
};

}  // namespace millkit::numerics
