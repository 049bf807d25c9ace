# Optional packages: every find_package that is not REQUIRED goes through drape_find_optional,
# so one switch builds the project as on a machine that has none of them, and the configure
# log lists what was found. Sources that need an optional package are added only inside an
# `if(<Name>_FOUND)` (or the package's own found variable) block.
#
#   -DDRAPE_OPTIONAL_PACKAGES=OFF   look for none of them (tools/run-tests.sh's sanitizer build
#                                   does this, proving a fresh machine builds and passes)
#
# A macro, not a function: find_package's result variables must land in the caller's scope.
option(DRAPE_OPTIONAL_PACKAGES "Look for optional packages (Bullet, ...); OFF builds as without them" ON)

macro(drape_find_optional name)
  if(DRAPE_OPTIONAL_PACKAGES)
    find_package(${name} ${ARGN} QUIET)
    if(${name}_FOUND)
      set_property(GLOBAL APPEND PROPERTY DRAPE_OPTIONAL_FOUND ${name})
    else()
      set_property(GLOBAL APPEND PROPERTY DRAPE_OPTIONAL_MISSING ${name})
    endif()
  else()
    set(${name}_FOUND FALSE)
    set_property(GLOBAL APPEND PROPERTY DRAPE_OPTIONAL_MISSING "${name} (disabled)")
  endif()
endmacro()

# One line at the end of configuring: what was compiled in and what was left out.
function(drape_optional_summary)
  get_property(found GLOBAL PROPERTY DRAPE_OPTIONAL_FOUND)
  get_property(missing GLOBAL PROPERTY DRAPE_OPTIONAL_MISSING)
  list(REMOVE_DUPLICATES found)  # a package two folders look for (Python3: the module, the tests)
  list(REMOVE_DUPLICATES missing)
  list(JOIN found ", " found)
  list(JOIN missing ", " missing)
  message(STATUS "drape optional packages: found [${found}], left out [${missing}]")
endfunction()
