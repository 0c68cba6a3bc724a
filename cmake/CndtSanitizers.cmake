# CNDT_SANITIZE: empty, "address,undefined" or "thread". Applied to every target of the build tree,
# since sanitizer runtimes must see the whole program.
set(CNDT_SANITIZE "" CACHE STRING "Sanitizers to build with: address,undefined | thread | empty")
if(CNDT_SANITIZE)
  message(STATUS "cndt: building with -fsanitize=${CNDT_SANITIZE}")
  add_compile_options(-fsanitize=${CNDT_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${CNDT_SANITIZE})
  if(CNDT_SANITIZE MATCHES "thread" AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    # GCC warns that TSan does not model atomic_thread_fence, which Boost.Asio's handler
    # invocation uses; cndt's own code synchronises through atomics and the SPSC rings.
    add_compile_options(-Wno-tsan)
  endif()
endif()
