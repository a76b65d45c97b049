// The seqlock moved to core/ (the drivers' I/O threads publish through it too).
#pragma once

#include "core/seqlock.hpp"
