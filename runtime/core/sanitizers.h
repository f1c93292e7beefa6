// Which sanitizer this translation unit is built with, for GCC and clang alike: GCC defines
// __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__, clang answers __has_feature (the sanitizer builds
// use clang, the Release build GCC: tools/test.sh). MOCAP_ASAN / MOCAP_TSAN are 1 or 0.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define MOCAP_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MOCAP_ASAN 1
#endif
#endif
#ifndef MOCAP_ASAN
#define MOCAP_ASAN 0
#endif

#if defined(__SANITIZE_THREAD__)
#define MOCAP_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define MOCAP_TSAN 1
#endif
#endif
#ifndef MOCAP_TSAN
#define MOCAP_TSAN 0
#endif
