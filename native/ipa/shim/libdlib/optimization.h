// roomseg-bench: ROS's libdlib package installs dlib under libdlib/; Debian's libdlib-dev under dlib/.
#include <dlib/optimization.h>
