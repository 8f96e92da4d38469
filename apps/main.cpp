#include <iostream>
int main() {
  std::cout << "fracvi\n";
}
