// The native kernel's Python module, ffsr_gym._native: the typed model and physics (bind_model.cpp), the loop,
// episodes and batches (bind_episode.cpp), the score's terms and the
// tumbling target's motion (bind_terms.cpp), the kernel's parts one at a time (bind_parts.cpp), the capture judge
// (bind_capture.cpp).
#include <nanobind/nanobind.h>

namespace nb = nanobind;

void bind_model(nb::module_& m);
void bind_episode(nb::module_& m);
void bind_terms(nb::module_& m);
void bind_parts(nb::module_& m);
void bind_capture(nb::module_& m);

NB_MODULE(_native, m) {
  m.doc() = "The native kernel of ffsr-gym: the typed robot model and its physics, compiled at install.";
  bind_model(m);
  bind_episode(m);
  bind_terms(m);
  bind_parts(m);
  bind_capture(m);
  m.attr("SOURCE_SHA256") = FFSR_SOURCE_SHA256;  // the sources' digest (CMakeLists.txt)
}
