// The live receiver gets every packet of a simulated capture sent over loopback at the sensor's
// rate, and refuses packets from another source address; a consumer waiting for packets sleeps
// rather than polls, and wakes for a packet or a stop.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <atomic>
#include <boost/asio.hpp>
#include <thread>
#include <utility>

#include "cndt/net/udp_source.hpp"
#include "cndt/sim/lidar_sim.hpp"

namespace cndt::net {
namespace {

using boost::asio::ip::udp;

// Data packets on a free loopback port; no position port.
UdpOptions loopback_any_port() {
  UdpOptions o;
  o.bind_address = "127.0.0.1";
  o.data_port = 0;
  o.position_port = 0;
  return o;
}

TEST(UdpSource, ReceivesEveryPacketAtSensorRateAndRejectsOtherSources) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 1.0, 2, 1);
  sim::LidarSimOptions so;
  so.duration_s = 1.0;
  sim::LidarSimulator simulator(scene, so);
  std::vector<std::array<std::uint8_t, 1206>> packets;
  sim::SimPacket p;
  while (simulator.next(p)) packets.push_back(p.payload);
  ASSERT_EQ(packets.size(), 754u);

  UdpOptions o = loopback_any_port();
  o.sensor_ip = io::IpAddress::parse("127.0.0.1");
  auto opened = UdpSource::open(o);
  ASSERT_TRUE(opened) << opened.error().message;
  UdpSource& source = *opened.value();
  const std::uint16_t port = source.data_port();

  std::vector<std::array<std::uint8_t, 1206>> received;
  std::atomic<bool> sending_done{false};
  std::thread consumer([&] {
    io::SourcePacket in;
    while (true) {
      const auto r = source.next(in, std::chrono::milliseconds(200));
      if (r == io::NextResult::kPacket) {
        std::array<std::uint8_t, 1206> copy{};
        ASSERT_EQ(in.payload.size(), 1206u);
        std::copy(in.payload.begin(), in.payload.end(), copy.begin());
        received.push_back(copy);
      } else if (sending_done.load()) {
        break;
      }
    }
  });

  boost::asio::io_context io;
  udp::socket sensor(io, udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  udp::socket intruder(io, udp::endpoint(boost::asio::ip::make_address("127.0.0.2"), 0));
  const udp::endpoint target(boost::asio::ip::make_address("127.0.0.1"), port);
  // Paced like the sensor: one packet every 1327.104 us.
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < packets.size(); ++k) {
    std::this_thread::sleep_until(
        start + std::chrono::nanoseconds(1'327'104LL * static_cast<long long>(k)));
    sensor.send_to(boost::asio::buffer(packets[k]), target);
    if (k % 15 == 0) intruder.send_to(boost::asio::buffer(packets[k]), target);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  sending_done.store(true);
  consumer.join();
  source.stop();

  const UdpStats s = source.stats();
  EXPECT_EQ(s.wrong_source, 51u);  // k = 0, 15, ..., 750
  EXPECT_EQ(s.queue_full, 0u);
  EXPECT_EQ(s.accepted, packets.size());
  ASSERT_EQ(received.size(), packets.size());
  for (std::size_t k = 0; k < packets.size(); ++k) {
    ASSERT_EQ(received[k], packets[k]) << "packet " << k;
  }
}

// Voluntary context switches of the calling thread so far.
long thread_switches() {
  rusage u{};
  getrusage(RUSAGE_THREAD, &u);
  return u.ru_nvcsw;
}

// With nothing arriving, next() sleeps until its timeout (a few wake-ups, not one every few
// hundred microseconds), a packet ends the wait at once, and so does stop().
TEST(UdpSource, AWaitingConsumerSleepsAndWakesForAPacketOrAStop) {
  auto opened = UdpSource::open(loopback_any_port());
  ASSERT_TRUE(opened) << opened.error().message;
  UdpSource& source = *opened.value();
  using Clock = std::chrono::steady_clock;
  const auto ms_since = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };

  io::SourcePacket in;
  std::atomic<long> idle_switches{-1};
  std::atomic<double> timeout_ms{0.0}, packet_ms{0.0}, stop_ms{0.0};
  std::atomic<int> results{0};
  std::atomic<bool> waiting_for_packet{false}, waiting_for_stop{false};
  std::thread consumer([&] {
    const long before = thread_switches();
    auto t = Clock::now();
    if (source.next(in, std::chrono::milliseconds(300)) == io::NextResult::kTimeout) ++results;
    timeout_ms = ms_since(t);
    idle_switches = thread_switches() - before;
    t = Clock::now();
    waiting_for_packet = true;
    if (source.next(in, std::chrono::seconds(20)) == io::NextResult::kPacket) ++results;
    packet_ms = ms_since(t);
    t = Clock::now();
    waiting_for_stop = true;
    if (source.next(in, std::chrono::seconds(20)) == io::NextResult::kEnd) ++results;
    stop_ms = ms_since(t);
  });
  const auto wait_until = [](const std::atomic<bool>& flag) {
    while (!flag.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // asleep in next() by now
  };
  wait_until(waiting_for_packet);
  boost::asio::io_context io;
  udp::socket sensor(io, udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  const std::array<std::uint8_t, 1206> payload{};
  sensor.send_to(boost::asio::buffer(payload),
                 udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), source.data_port()));
  wait_until(waiting_for_stop);
  source.stop();
  consumer.join();
  EXPECT_EQ(results.load(), 3);
  EXPECT_GE(timeout_ms.load(), 299.0);
  EXPECT_LT(idle_switches.load(), 30);  // polling every 200 us would be about 1,500
  EXPECT_LT(packet_ms.load(), 2000.0);  // the packet came after 100 ms
  EXPECT_LT(stop_ms.load(), 2000.0);    // stop() after 100 ms
}

TEST(UdpSource, BindFailureNamesTheAddress) {
  auto first = UdpSource::open(loopback_any_port());
  ASSERT_TRUE(first);
  UdpOptions bad;
  bad.bind_address = "not-an-address";
  auto r = UdpSource::open(bad);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("not-an-address"), std::string::npos);
  UdpOptions foreign;
  foreign.bind_address = "192.0.2.1";  // TEST-NET: not an address of this machine
  foreign.data_port = 0;
  foreign.position_port = 0;
  auto r2 = UdpSource::open(foreign);
  ASSERT_FALSE(r2);
  EXPECT_NE(r2.error().message.find("192.0.2.1"), std::string::npos);
}

}  // namespace
}  // namespace cndt::net
