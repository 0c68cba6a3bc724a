# Per-target warnings: cndt_set_warnings(<target>) applies the project's warning set to one target
# instead of changing global flags, so third-party headers and generated code are unaffected.
function(cndt_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion
                                           -Wshadow -Wnon-virtual-dtor -Wold-style-cast)
  if(CNDT_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
