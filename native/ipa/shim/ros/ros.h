// roomseg-bench: a stand-in for <ros/ros.h> so ipa_room_segmentation's algorithm sources build
// without ROS. They use ROS only for logging (ROS_INFO, ROS_ERROR, ...): these print to stderr,
// where the driver's caller keeps the last line when a map fails.
#ifndef ROOMSEG_IPA_SHIM_ROS_H
#define ROOMSEG_IPA_SHIM_ROS_H
#include <cstdio>
#include <sys/time.h>  // ROS headers bring it; the authors' timer.h relies on that
#define ROOMSEG_IPA_LOG(level, ...) (std::fprintf(stderr, "[" level "] " __VA_ARGS__), std::fputc('\n', stderr))
#define ROS_DEBUG(...) ((void)0)
#define ROS_INFO(...) ((void)0)
#define ROS_WARN(...) ROOMSEG_IPA_LOG("WARN", __VA_ARGS__)
#define ROS_ERROR(...) ROOMSEG_IPA_LOG("ERROR", __VA_ARGS__)
#define ROS_FATAL(...) ROOMSEG_IPA_LOG("FATAL", __VA_ARGS__)
#endif
