# append_raw_string(BODY TEXT DELIM): appends TEXT to the variable BODY as C++ raw string literals of at most
# 8000 characters each (some compilers limit a literal's length; adjacent literals concatenate), or "" when
# TEXT is empty. DELIM is the raw strings' delimiter, which TEXT must not contain followed by a quote.
function(append_raw_string BODY TEXT DELIM)
  set(out "${${BODY}}")
  string(LENGTH "${TEXT}" len)
  set(pos 0)
  while(pos LESS len)
    string(SUBSTRING "${TEXT}" ${pos} 8000 chunk)
    string(APPEND out "R\"${DELIM}(${chunk})${DELIM}\"\n")
    math(EXPR pos "${pos} + 8000")
  endwhile()
  if(len EQUAL 0)
    string(APPEND out "\"\"\n")
  endif()
  set(${BODY} "${out}" PARENT_SCOPE)
endfunction()
