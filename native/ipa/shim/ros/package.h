// roomseg-bench: <ros/package.h> without ROS. The driver passes the package's folder explicitly
// (--models); nothing it compiles asks ROS for a package path.
#ifndef ROOMSEG_IPA_SHIM_ROS_PACKAGE_H
#define ROOMSEG_IPA_SHIM_ROS_PACKAGE_H
#include <string>
#endif
