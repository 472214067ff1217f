/* The single header bindgen reads for Embree 3 (Debian's libembree-dev). Only `rtc*`/`RTC*` items
 * are kept (see build.rs); `rtcInitIntersectContext` is static inline and is re-done in Rust. */
#pragma once
#include <embree3/rtcore.h>
