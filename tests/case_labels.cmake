# The labels and locks of each gtest case by its name (Suite.Case), added to those of its
# executable. Read by CTest once an executable's cases are known: loopwire_discover_tests
# (tests/CMakeLists.txt) includes it with `loopwire_cases` set to the executable's cases, and
# `loopwire_cases_with_peers` when some of them start peers (their executable then labels none
# `unit`: a case is `unit` or `peer` here). A name with brackets in it (a parameter such as
# tcp://[::1]) cannot be taken out of a CMake list whole: such a case keeps its executable's
# labels only. Read by CMake too, without `loopwire_cases`, for the gtest filter of the
# wall-clock-sensitive cases (a sanitizer's build runs them apart from its shards).
#
#   peer          the case starts a real program beside it (mosquitto, PostgreSQL); not `unit`
#   virtual-time  the case's waits run on a virtual clock (common/clock.hpp): no wall time passes
#   slow          over about 30 s in the plain build
#   RESOURCE_LOCK wall_clock_sensitive: the case asserts real-time pacing (cadences, latencies,
#                 wire timing), which another such test beside it on a loaded machine could starve
#
# A suite named here is the rule for its cases; a new suite of that kind belongs here too.
set(loopwire_peer_cases "^(MqttBridge|SparkplugNode|HistoryForward|HistorianReaderTest)\\.")
set(loopwire_virtual_time_cases
  "^(VirtualClock|LineLoopEventsTimers|LineSchedulerTest|BoundedLineSchedulerTest|StrayReplies|HistoryStore|ReopeningMasterTest|ConcurrentReopeningMaster|ReopeningMasterOnALoop|ValueCacheStaleness|ValueCacheStalenessThreads|LineSoak|StaleHistory|Staleness|SlaveInVirtualTime)\\.|VirtualTime|InjectedClock")
set(loopwire_slow_cases "^(LineSoak\\.|RestoreOnFaultyBus\\.Ac20StopsInControlModeOrCompletes$)")
set(loopwire_wall_clock_suites GatewayOnFaultyBus Gateway MonitorOnFaultyBus RestoreOnFaultyBus VirtualBus
  TcpSlaveHostileClients TcpSlaveServer HttpLimitsTest)
set(loopwire_wall_clock_single_cases HttpApiTest.AStalledClientIsClosedWithoutHoldingUpOthers)

# The same, as a regular expression and as a gtest filter ("Suite.*:Suite.Case").
list(JOIN loopwire_wall_clock_suites "|" loopwire_joined)
list(JOIN loopwire_wall_clock_single_cases "|" loopwire_joined_cases)
string(REPLACE "." "\\." loopwire_joined_cases "${loopwire_joined_cases}")
set(loopwire_wall_clock_cases "^(${loopwire_joined})\\.|^(${loopwire_joined_cases})$")
list(JOIN loopwire_wall_clock_suites ".*:" loopwire_joined)
list(JOIN loopwire_wall_clock_single_cases ":" loopwire_joined_cases)
set(loopwire_wall_clock_filter "${loopwire_joined}.*:${loopwire_joined_cases}")

foreach(loopwire_case IN LISTS loopwire_cases)
  set(loopwire_labels "")
  if(NOT loopwire_cases_with_peers)
  elseif(loopwire_case MATCHES "${loopwire_peer_cases}")
    list(APPEND loopwire_labels peer)
  else()
    list(APPEND loopwire_labels unit)
  endif()
  if(loopwire_case MATCHES "${loopwire_virtual_time_cases}")
    list(APPEND loopwire_labels virtual-time)
  endif()
  if(loopwire_case MATCHES "${loopwire_slow_cases}")
    list(APPEND loopwire_labels slow)
  endif()
  if(loopwire_labels)
    set_tests_properties("${loopwire_case}" PROPERTIES LABELS "${loopwire_labels}")
  endif()
  if(loopwire_case MATCHES "${loopwire_wall_clock_cases}")
    set_tests_properties("${loopwire_case}" PROPERTIES RESOURCE_LOCK wall_clock_sensitive)
  endif()
endforeach()
