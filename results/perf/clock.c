#include <stdio.h>
#include <time.h>
int main(){
  struct timespec a,b; unsigned long x=1, n=2000000000UL;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID,&a);
  for(unsigned long i=0;i<n;i+=10){
    __asm__ volatile("add %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0\n\tadd %1,%0":"+r"(x):"r"(i));
  }
  clock_gettime(CLOCK_THREAD_CPUTIME_ID,&b);
  double s=(b.tv_sec-a.tv_sec)+(b.tv_nsec-a.tv_nsec)*1e-9;
  printf("%lu dependent adds in %.3f s CPU: %.2f GHz (x=%lu)\n",n,s,n/s/1e9,x);
}
