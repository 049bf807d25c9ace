# cmake -DNPM=… -DSOURCE_DIR=apps/viewer -DWORK_DIR=<build>/apps/viewer -P build.cmake
# Installs the locked packages into WORK_DIR (never into the source tree) and bundles
# src/main.js with three.js into WORK_DIR/dist/viewer.js. A failure (no network) is a warning.
file(COPY ${SOURCE_DIR}/package.json ${SOURCE_DIR}/package-lock.json DESTINATION ${WORK_DIR})
file(COPY ${SOURCE_DIR}/src DESTINATION ${WORK_DIR})
execute_process(COMMAND ${NPM} ci --no-audit --no-fund --loglevel=error
                WORKING_DIRECTORY ${WORK_DIR} RESULT_VARIABLE npm_result OUTPUT_VARIABLE npm_out ERROR_VARIABLE npm_out)
if(NOT npm_result EQUAL 0)
  message(WARNING "drape viewer not built: npm ci failed (is the npm registry reachable?):\n${npm_out}")
  file(REMOVE ${WORK_DIR}/dist/viewer.js ${WORK_DIR}/dist/index.html)
  return()
endif()
execute_process(COMMAND ${WORK_DIR}/node_modules/.bin/esbuild src/main.js --bundle --format=esm --minify
                        --log-level=warning --outfile=dist/viewer.js
                WORKING_DIRECTORY ${WORK_DIR} RESULT_VARIABLE esbuild_result)
if(NOT esbuild_result EQUAL 0)
  message(FATAL_ERROR "drape viewer: esbuild failed on src/main.js")
endif()
file(COPY ${WORK_DIR}/src/index.html DESTINATION ${WORK_DIR}/dist)
