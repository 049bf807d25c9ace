// Everything a program embedding drape needs.
#pragma once

#include <drape/constraint.h>
#include <drape/motion.h>
#include <drape/obstacle.h>
#include <drape/sheet.h>
#include <drape/types.h>
#include <drape/world.h>
