// stereo: work in progress (see the open issue).
#include "safenav/stereo.hpp"
