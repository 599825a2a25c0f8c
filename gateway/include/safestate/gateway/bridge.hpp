// The bridge headers as the gateway includes them. The gateway is the side that reads
// the seqlocks, and SeqLock<T>::read memcpy's into a T (Status, BlackBoxRecord) whose
// default member initialisers make it trivially copyable but not trivial: GCC's
// -Wclass-memaccess flags that memcpy although it is well-defined. Silenced here, for
// the bridge headers only, until layout.hpp writes `static_cast<void*>(&out)`.
// Include this before anything that includes the bridge headers.
#pragma once

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wclass-memaccess"
#endif
#include "safestate/bridge/layout.hpp"
#include "safestate/bridge/segment.hpp"
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
