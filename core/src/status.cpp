// SPEC §10, §11 as the status shows them (protocol `safety`): one cycle's facts of the
// safe-limit and collaborative monitors, copied once into the supervisor's output.
#include "safestate/core/supervisor.hpp"

namespace safestate::core {

void safety_status(const CycleFacts& f, const SafeLimitMonitors& limits, bool validated, const SafetyInputs& in,
                   SafetyStatus& st) noexcept {
  st.checksum = limits.limits().checksum;
  st.validated = validated;
  st.reduced = limits.reduced().active();
  st.reduced_by = limits.reduced().sources();
  st.recovery = f.limits.recovering;
  st.outside = f.limits.outside;
  st.speed_limit_mm_s = f.limits.speed_limit_mm_s;
  st.tcp_speed_mm_s = f.limits.tcp_speed_mm_s;
  st.field_outer_interrupted = in.field_outer_interrupted;
  st.field_inner_interrupted = in.field_inner_interrupted;
  st.ssm = f.ssm.acting;
  st.v_allowed_mm_s = f.ssm.v_allowed_mm_s;
  st.separation_mm = f.ssm.separation_mm;
  st.pfl = f.collision.acting;
  st.contact_force_n = f.collision.force_n;
}

}  // namespace safestate::core
